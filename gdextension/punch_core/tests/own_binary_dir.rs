//! `runtime::own_binary_dir` finds the folder of the binary the core is linked into: in Godot the extension's
//! library (where ONNX Runtime is shipped beside it), here this test program. Run on Linux (`dladdr`) and, as a
//! Windows program under Wine, on Windows (`GetModuleHandleExW`).

use punch_core::inference::runtime;

#[test]
fn own_binary_dir_is_the_folder_of_the_binary_holding_the_core() {
    let found = runtime::own_binary_dir().expect("the folder of this test program");
    let exe = std::env::current_exe().expect("current exe");
    let expected = exe.parent().expect("a folder");
    assert_eq!(
        found.canonicalize().expect("canonical found"),
        expected.canonicalize().expect("canonical expected"),
        "{found:?} is not {expected:?}"
    );
}
