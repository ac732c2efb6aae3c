//! Data layouts of one's own ([`DataFormat`]), registered by name
//! ([`FormatRegistry`]): [`crate::Dataset::open_with`] reads a folder that none of
//! the built-in layouts (D-NeRF, Plenoptic Video, Dynamic 3D Gaussians) claims with
//! the first registered format whose [`DataFormat::detect`] accepts it
//! (docs/extending.md, "A data format").

use std::path::Path;
use std::sync::Arc;

use maaf_io::Registry;

use crate::dnerf::{Frame, Split, SplitMeta};
use crate::error::DataError;
use crate::image::image_size;

/// The built-in layouts' names, which no registered format takes.
pub const BUILTIN_FORMATS: [&str; 3] = ["dnerf", "plenoptic", "dynamic3dgs"];

/// A data layout of one's own: how to recognise a folder in it and read its splits.
pub trait DataFormat: Send + Sync {
    /// Whether `root` is in this layout (typically: a marker file exists). Cheap and
    /// without errors; a folder it accepts but [`DataFormat::load`] cannot read is
    /// refused with the loader's error.
    fn detect(&self, root: &Path) -> bool;

    /// The splits of the data set in `root`: `train` and `test` required, `val` and
    /// `video` optional, each built with [`SplitMeta::from_frames`] (or field by
    /// field). Cameras are checked and images must share one size afterwards, as for
    /// every layout; an error names the file and the field at fault.
    fn load(&self, root: &Path) -> Result<Vec<SplitMeta>, DataError>;
}

impl SplitMeta {
    /// The split `split` of a layout of one's own, described by `source` (the file
    /// that lists it, named in errors) and holding `frames` (image path, time, camera
    /// at the image's size in OpenCV axes, no flow). Reads every image header and
    /// refuses an empty split, an image that does not decode, and an image whose size
    /// is not its camera's or the first image's; the field of view is the first
    /// camera's, and the scene bounds come from the training cameras.
    pub fn from_frames(
        split: Split,
        source: &Path,
        frames: Vec<Frame>,
    ) -> Result<SplitMeta, DataError> {
        let Some(first) = frames.first() else {
            return Err(DataError::field(source, split.name(), "has no views"));
        };
        let (width, height) = (first.camera.width, first.camera.height);
        let focal = first.camera.fx;
        for (i, f) in frames.iter().enumerate() {
            let size = image_size(&f.file)?;
            if size != (f.camera.width, f.camera.height) || size != (width, height) {
                return Err(DataError::field(
                    source,
                    format!("{}[{i}]", split.name()),
                    format!(
                        "{} is {}x{} but its camera is {}x{} and the split's first {width}x{height}",
                        f.file.display(),
                        size.0,
                        size.1,
                        f.camera.width,
                        f.camera.height
                    ),
                ));
            }
        }
        Ok(SplitMeta {
            split,
            json: source.to_path_buf(),
            camera_angle_x: 2.0 * (0.5 * f64::from(width) / focal).atan(),
            width,
            height,
            focal,
            frames,
            scene_bounds: None,
        })
    }
}

/// Registered data layouts, consulted in registration order after the built-in
/// ones. Empty by default; a program adds its own (`maaf::cli::Maaf::data_format`).
/// Cloning shares the formats.
#[derive(Clone, Debug)]
pub struct FormatRegistry {
    formats: Registry<dyn DataFormat>,
}

impl Default for FormatRegistry {
    fn default() -> Self {
        FormatRegistry {
            formats: Registry::new("data format", "maaf::cli::Maaf::data_format"),
        }
    }
}

impl FormatRegistry {
    /// A registry with no layout of one's own.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `format` under `name` (1 to 64 letters, digits or `_`); refuses a name
    /// already registered or a built-in layout's ([`BUILTIN_FORMATS`]).
    pub fn register<F: DataFormat + 'static>(
        &mut self,
        name: &str,
        format: F,
    ) -> Result<(), String> {
        if BUILTIN_FORMATS.contains(&name) {
            return Err(format!("data format `{name}` is built in"));
        }
        self.formats.register(name, Arc::new(format))
    }

    /// The registered names, in registration (and detection) order.
    pub fn names(&self) -> Vec<&str> {
        self.formats.names()
    }

    /// The first registered format that detects `root`, with its name.
    pub fn detect(&self, root: &Path) -> Option<(&str, &dyn DataFormat)> {
        self.formats
            .iter()
            .find(|(_, f)| f.detect(root))
            .map(|(n, f)| (n, f.as_ref()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A layout recognised by a marker file, with no views.
    struct Marker(&'static str);

    impl DataFormat for Marker {
        fn detect(&self, root: &Path) -> bool {
            root.join(self.0).is_file()
        }
        fn load(&self, _: &Path) -> Result<Vec<SplitMeta>, DataError> {
            Ok(Vec::new())
        }
    }

    #[test]
    fn duplicate_builtin_and_malformed_names_are_refused() {
        let mut r = FormatRegistry::new();
        r.register("mine", Marker("a")).expect("new name");
        let err = r.register("mine", Marker("b")).expect_err("duplicate");
        assert_eq!(
            err,
            "data format `mine` is already registered (registered: mine)"
        );
        for name in BUILTIN_FORMATS {
            assert!(r.register(name, Marker("c")).is_err(), "{name}");
        }
        assert!(r.register("my format", Marker("d")).is_err());
        assert_eq!(r.names(), ["mine"]);
    }

    #[test]
    fn the_first_format_that_detects_the_folder_reads_it() {
        let dir = std::env::temp_dir().join(format!("maaf_format_detect_{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        std::fs::write(dir.join("b.json"), "{}").expect("marker");
        let mut r = FormatRegistry::new();
        r.register("a", Marker("a.json")).expect("a");
        r.register("b", Marker("b.json")).expect("b");
        r.register("also_b", Marker("b.json")).expect("also b");
        assert_eq!(r.detect(&dir).map(|(n, _)| n), Some("b"));
        std::fs::remove_dir_all(&dir).expect("cleans up");
        assert!(r.detect(&dir).is_none());
    }

    #[test]
    fn an_empty_split_is_refused_naming_its_file() {
        let err = SplitMeta::from_frames(Split::Test, Path::new("views.json"), Vec::new())
            .expect_err("empty");
        assert!(err.to_string().contains("views.json"), "{err}");
        assert!(err.to_string().contains("no views"), "{err}");
    }
}
