//! What a checkpoint carries besides the model so that the run loads, renders and is
//! evaluated without its data set: the training views' cameras and times, the box of
//! the point cloud the representation was built from, the data set's time range and
//! background. Saved as `scene/*` tensors in `tensors.safetensors` (f64 where the
//! value is f64, so a reload is exact); checkpoints written before it existed have
//! none, and their runs need the data set ([`SceneRecord::of_data`]).

use std::path::Path;

use maaf_data::{Dataset, Split};
use maaf_models::{ModelInit, PointCloud};
use maaf_splat::Camera;
use safetensors::{Dtype, SafeTensors};

use crate::checkpoint_read::bytes_of;
use crate::{Error, TrainConfig, camera_extent, model_init};

const CAMERAS: &str = "scene/cameras";
const VIEWS: &str = "scene/views";
const INIT_BOX: &str = "scene/init_box";
const TIME_RANGE: &str = "scene/time_range";
const BACKGROUND: &str = "scene/background";

/// Numbers per camera in `scene/cameras`: width, height, fx, fy, cx, cy and the
/// row-major 4x4 world-to-camera matrix.
const CAMERA_WIDTH: usize = 22;

/// The data-set facts of a trained run (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneRecord {
    /// Camera of every training view at the training scale, in split order.
    pub cameras: Vec<Camera>,
    /// Time of every training view, in split order.
    pub times: Vec<f64>,
    /// `(min, max)` of the initial point cloud ([`PointCloud::bounds`]): what a
    /// representation may derive from the cloud besides its parameters (SaRO's
    /// K-plane normalisation box).
    pub init_box: ([f64; 3], [f64; 3]),
    /// `(min, max)` of the data set's time stamps over all splits.
    pub time_range: (f64, f64),
    /// Background colour the training images were composited on.
    pub background: [f32; 3],
}

/// One named tensor to save: name, element type, shape, little-endian bytes.
pub type RawTensor = (String, Dtype, Vec<usize>, Vec<u8>);

fn f64_bytes(values: impl IntoIterator<Item = f64>) -> Vec<u8> {
    values.into_iter().flat_map(f64::to_le_bytes).collect()
}

impl SceneRecord {
    /// The record of a run on `data` with `config`, from the data set: for runs whose
    /// checkpoints predate the record. Rebuilds the initial cloud ([`model_init`]) for
    /// its box, as training did.
    pub fn of_data(data: &Dataset, config: &TrainConfig) -> Result<Self, Error> {
        let input = |e: maaf_data::DataError| Error::Input(e.to_string());
        let cameras = data
            .cameras(Split::Train, config.train_scale)
            .map_err(input)?;
        let init = model_init(data, config)?;
        Ok(SceneRecord {
            cameras,
            times: data.times(Split::Train),
            init_box: init.cloud.bounds(),
            time_range: data.time_range(),
            background: data.background(),
        })
    }

    /// What the representation of a run of `config` is rebuilt from: the 8 corners of
    /// the initial cloud's box (so its bounds are the saved ones), the training
    /// cameras' extent, the run's seed, the distinct training times and the run's
    /// iterations, as [`model_init`] gave them at training. The corners stand in for
    /// the cloud: a representation's tensors come from the checkpoint.
    pub fn model_init(&self, config: &TrainConfig) -> ModelInit {
        let (lo, hi) = self.init_box;
        let points: Vec<[f64; 3]> = (0..8)
            .map(|c| std::array::from_fn(|a| if c >> a & 1 == 0 { lo[a] } else { hi[a] }))
            .collect();
        let mut times = self.times.clone();
        times.sort_by(f64::total_cmp);
        times.dedup();
        ModelInit {
            cloud: PointCloud {
                colours: vec![[0.5; 3]; points.len()],
                points,
                times: None,
            },
            extent: camera_extent(&self.cameras),
            seed: config.seed,
            times,
            iterations: config.iterations,
        }
    }

    /// The record as checkpoint tensors (the views' cameras stored once each).
    pub fn to_tensors(&self) -> Vec<RawTensor> {
        let mut distinct: Vec<&Camera> = Vec::new();
        let mut views = Vec::with_capacity(2 * self.times.len());
        for (cam, &t) in self.cameras.iter().zip(&self.times) {
            let k = match distinct.iter().position(|c| *c == cam) {
                Some(k) => k,
                None => {
                    distinct.push(cam);
                    distinct.len() - 1
                }
            };
            views.extend([k as f64, t]);
        }
        let cameras = distinct.iter().flat_map(|c| {
            [c.width, c.height]
                .map(f64::from)
                .into_iter()
                .chain([c.fx, c.fy, c.cx, c.cy])
                .chain(c.world_to_camera.iter().flatten().copied())
        });
        let (lo, hi) = self.init_box;
        let (t0, t1) = self.time_range;
        vec![
            (
                CAMERAS.into(),
                Dtype::F64,
                vec![distinct.len(), CAMERA_WIDTH],
                f64_bytes(cameras),
            ),
            (
                VIEWS.into(),
                Dtype::F64,
                vec![self.times.len(), 2],
                f64_bytes(views),
            ),
            (
                INIT_BOX.into(),
                Dtype::F64,
                vec![2, 3],
                f64_bytes(lo.into_iter().chain(hi)),
            ),
            (TIME_RANGE.into(), Dtype::F64, vec![2], f64_bytes([t0, t1])),
            (
                BACKGROUND.into(),
                Dtype::F32,
                vec![3],
                bytes_of(&self.background),
            ),
        ]
    }

    /// The record in a checkpoint's tensors, `None` when it has none (written before
    /// the record existed). Errors name the file and the malformed tensor.
    pub fn from_tensors(st: &SafeTensors<'_>, file: &Path) -> Result<Option<Self>, Error> {
        if st.tensor(VIEWS).is_err() {
            return Ok(None);
        }
        let bad = |name: &str, why: String| {
            Error::Input(format!("{}: tensor `{name}`: {why}", file.display()))
        };
        let read = |name: &str, dtype: Dtype| -> Result<(Vec<usize>, Vec<u8>), Error> {
            let view = st.tensor(name).map_err(|e| bad(name, e.to_string()))?;
            if view.dtype() != dtype {
                return Err(bad(
                    name,
                    format!("is {:?}, expected {dtype:?}", view.dtype()),
                ));
            }
            Ok((view.shape().to_vec(), view.data().to_vec()))
        };
        let f64s = |name: &str, shape: &dyn Fn(&[usize]) -> bool| -> Result<Vec<f64>, Error> {
            let (s, bytes) = read(name, Dtype::F64)?;
            if !shape(&s) {
                return Err(bad(name, format!("unexpected shape {s:?}")));
            }
            Ok(bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
                .collect())
        };
        let distinct = f64s(CAMERAS, &|s| s.len() == 2 && s[1] == CAMERA_WIDTH)?;
        let distinct: Vec<Camera> = distinct
            .chunks_exact(CAMERA_WIDTH)
            .map(|c| {
                let w2c = std::array::from_fn(|r| std::array::from_fn(|k| c[6 + 4 * r + k]));
                Camera::new(c[0] as u32, c[1] as u32, c[2], c[3], c[4], c[5], w2c)
                    .map_err(|e| bad(CAMERAS, e.to_string()))
            })
            .collect::<Result<_, _>>()?;
        let views = f64s(VIEWS, &|s| s.len() == 2 && s[1] == 2)?;
        let mut cameras = Vec::with_capacity(views.len() / 2);
        let mut times = Vec::with_capacity(views.len() / 2);
        for v in views.chunks_exact(2) {
            let cam = distinct
                .get(v[0] as usize)
                .ok_or_else(|| bad(VIEWS, format!("camera index {} out of range", v[0])))?;
            cameras.push(cam.clone());
            times.push(v[1]);
        }
        let b = f64s(INIT_BOX, &|s| s == [2, 3])?;
        let r = f64s(TIME_RANGE, &|s| s == [2])?;
        let (s, bytes) = read(BACKGROUND, Dtype::F32)?;
        if s != [3] {
            return Err(bad(BACKGROUND, format!("unexpected shape {s:?}")));
        }
        let bg: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap_or([0; 4])))
            .collect();
        Ok(Some(SceneRecord {
            cameras,
            times,
            init_box: ([b[0], b[1], b[2]], [b[3], b[4], b[5]]),
            time_range: (r[0], r[1]),
            background: [bg[0], bg[1], bg[2]],
        }))
    }
}
