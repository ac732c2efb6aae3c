//! Helpers shared by the data tests (each test file declares `mod common;`).

use std::path::PathBuf;

/// A fresh, empty folder under the system temp dir, removed on drop. The name holds
/// `tag`, the process id and a per-process counter, so parallel tests never share one.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// Creates `maaf-test-{tag}-{pid}-{n}` (emptied first if a stale one exists).
    pub fn new(tag: &str) -> Self {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let p = std::env::temp_dir().join(format!(
            "maaf-test-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::SeqCst)
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("temp dir");
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
