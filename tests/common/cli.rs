//! Helpers of the CLI tests (`tests/cli*.rs`): the `penumbra` binary run in the repository root,
//! a fresh output folder, its stderr, and a clean failure with the messages expected.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn penumbra(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run penumbra")
}

pub fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("cli")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn assert_fails_with(args: &[&str], needles: &[&str]) {
    let o = penumbra(args);
    let err = stderr(&o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "expected a clean failure, got: {err}"
    );
    assert!(!err.contains("panicked"), "panicked: {err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks '{n}': {err}");
    }
}
