/* load_library DLL SYMBOL...: loads DLL as Windows does (every DLL it imports must be found) and looks up each
 * SYMBOL. Prints one line per step; exits 1 at the first failure. Used under Wine by tests/python/test_windows.py. */
#include <stdio.h>
#include <windows.h>

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: load_library DLL [SYMBOL...]\n");
        return 2;
    }
    HMODULE module = LoadLibraryA(argv[1]);
    if (!module) {
        printf("LOAD_FAILED %s (error %lu)\n", argv[1], GetLastError());
        return 1;
    }
    printf("LOADED %s\n", argv[1]);
    for (int i = 2; i < argc; i++) {
        if (!GetProcAddress(module, argv[i])) {
            printf("SYMBOL_MISSING %s\n", argv[i]);
            return 1;
        }
        printf("SYMBOL %s\n", argv[i]);
    }
    return 0;
}
