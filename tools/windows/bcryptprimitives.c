/* ProcessPrng, the one function of Windows 10's bcryptprimitives.dll that Rust's standard library imports (for
 * random numbers). Wine before 9.0 lacks the DLL, so programs built by Rust cannot start there; tools/windows/run
 * puts this stand-in into its own Wine prefix only. Real Windows has the DLL and never sees this file. */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length); /* RtlGenRandom, advapi32 */

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length) {
        ULONG chunk = length > 0x10000000 ? 0x10000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk)) return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
