//! The D-NeRF scene the training tests run on (each test file that needs it declares
//! `mod mutant;`).

use std::path::PathBuf;

/// The D-NeRF mutant scene at `../shared/data/dnerf/mutant`, where CI and the README's
/// set-up keep the D-NeRF scenes. A test that needs it fails naming the path when it is
/// absent, rather than passing without having run.
pub fn mutant_root() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/dnerf/mutant");
    assert!(
        dir.join("transforms_train.json").is_file(),
        "{}: the D-NeRF mutant scene is missing (README, \"Data\", says where the D-NeRF scenes come from)",
        dir.display()
    );
    dir
}
