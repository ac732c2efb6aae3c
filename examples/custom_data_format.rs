//! A data layout of your own in the whole `maaf` command line, written only against
//! maaf's public API: one `views.json` listing every view of each split with its
//! image, time and camera (the camera format of `maaf render --camera`: width,
//! height, fx, fy, cx, cy and the world-to-camera matrix in OpenCV axes):
//!
//! ```text
//! { "train": [ {"image": "images/train_000.png", "time": 0.0,
//!               "camera": {"width": 64, "height": 64, "fx": 68.6, "fy": 68.6,
//!                          "cx": 32.0, "cy": 32.0, "world_to_camera": [[...], ...]}},
//!              ... ],
//!   "test": [ ... ],
//!   "val": [ ... ] }                                   // val is optional
//! ```
//!
//! It implements `DataFormat` (recognise the folder by its `views.json`, read the
//! splits) and is registered under the name `views_json`; `--data` then takes such a
//! folder in every command:
//!
//! ```text
//! cargo run --release --example custom_data_format -- train --data SCENE --out RUN
//! cargo run --release --example custom_data_format -- eval --run RUN
//! cargo run --release --example custom_data_format -- inspect --data SCENE
//! ```
//!
//! The built-in layouts are tried first, so a D-NeRF folder that also holds a
//! `views.json` still reads as D-NeRF. `tests/cli/custom_plugins.rs` writes a
//! generated scene in this layout, trains and evaluates it.

use std::path::Path;

use maaf::splat::Camera;
use maaf::train::data::{DataError, DataFormat, Frame, Split, SplitMeta};
use serde::Deserialize;

// ---- the user's layout ----

/// The file that marks and describes a folder in this layout.
const LISTING: &str = "views.json";

/// `views.json`: the views of each split.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Listing {
    train: Vec<Entry>,
    test: Vec<Entry>,
    #[serde(default)]
    val: Option<Vec<Entry>>,
}

/// One view: its image (relative to the folder), time and camera.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    image: String,
    time: f64,
    camera: Camera,
}

/// A folder with a `views.json`.
struct ViewsJson;

impl DataFormat for ViewsJson {
    fn detect(&self, root: &Path) -> bool {
        root.join(LISTING).is_file()
    }

    fn load(&self, root: &Path) -> Result<Vec<SplitMeta>, DataError> {
        let path = root.join(LISTING);
        let text =
            std::fs::read_to_string(&path).map_err(|e| DataError::io(&path, "cannot read", e))?;
        let listing: Listing = serde_json::from_str(&text).map_err(|e| DataError::Json {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let mut splits = vec![(Split::Train, listing.train), (Split::Test, listing.test)];
        if let Some(val) = listing.val {
            splits.push((Split::Val, val));
        }
        splits
            .into_iter()
            .map(|(split, entries)| {
                let frames = entries
                    .into_iter()
                    .map(|e| Frame {
                        file: root.join(e.image),
                        time: e.time,
                        camera: e.camera,
                        flow: None,
                    })
                    .collect();
                SplitMeta::from_frames(split, &path, frames)
            })
            .collect()
    }
}

fn main() {
    maaf::cli::Maaf::new()
        .data_format("views_json", ViewsJson)
        .run()
}
