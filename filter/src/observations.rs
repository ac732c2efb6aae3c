//! Observations `(t_j, x_j = f_j / d_j)` of each Gaussian's deformed centre, the
//! input of Algorithm 1 (paper Sec. 4: "we create data {(t_i, f_i/d_i)} by
//! projecting primitives at every time stamp for all the training views").
//!
//! One slot per (Gaussian, training frame), like the paper's pre-allocated
//! observation slots (Alg. 1 "empty slots flagged by t_j < 0"; here an empty slot
//! holds `x = 0`, since a visible centre always has `x = f/z > 0`). A training
//! frame is one (camera, time) pair of the training set; its time is shared by all
//! Gaussians, so the table stores only `x` (4 bytes per slot).
//!
//! Two ways to fill it, same visibility rule ([`Viewer::visible_depth`]):
//! * [`ObservationTable::observe_all`]: the full pass. Calls the deformation once
//!   per distinct training time and projects into every camera of that time.
//! * [`ObservationTable::record_centres`] / [`ObservationTable::record_depths`]: the
//!   incremental recorder. The trainer hands over the deformed centres (or depths)
//!   it already computed in the forward pass of the step's (camera, time); the slot
//!   keeps the value from the last time that frame was trained on, so it can be
//!   stale (see the crate docs for the measured effect).
//!
//! The table is a per-Gaussian container: it implements [`PerGaussian`] and must
//! be resized together with the parameters at densification.

use maaf_autodiff::PerGaussian;
use maaf_splat::Camera;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::{FilterConfig, FilterError};
use crate::mip::Viewer;

/// One training view as the filter sees it: which camera, at which time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraTime {
    /// Index into the trainer's training cameras.
    pub camera: usize,
    /// CameraTime time (in the config's `time_range`).
    pub time: f32,
}

/// The training frames the motion filter observes, at most `max` of them
/// ([`crate::FilterConfig::max_views`]): all frames, in order, when there are no
/// more; otherwise every frame of an even stride of the distinct times (the most
/// times whose frames fit in `max`, at positions `floor(j G / g)` of the `G` times),
/// so each kept time keeps all its cameras. Thinning times rather than cameras
/// keeps the KDE's conditional density `p(x | t)` (a mode over the cameras of a
/// time) and only coarsens its time sampling, which the Gaussian time kernel
/// (`h_t`) smooths over. A single time with more than `max` cameras keeps an even
/// stride of them.
pub fn observed_frames(frames: &[CameraTime], max: usize) -> Vec<usize> {
    let f = frames.len();
    if f <= max {
        return (0..f).collect();
    }
    let mut order: Vec<usize> = (0..f).collect();
    order.sort_by(|&a, &b| {
        let (x, y) = (frames[a], frames[b]);
        x.time.total_cmp(&y.time).then(x.camera.cmp(&y.camera))
    });
    let mut starts: Vec<usize> = (0..f)
        .filter(|&i| i == 0 || frames[order[i]].time != frames[order[i - 1]].time)
        .collect();
    let groups = starts.len();
    starts.push(f);
    let pick = |g: usize| (0..g).map(move |j| j * groups / g);
    let size = |k: usize| starts[k + 1] - starts[k];
    let mut g = (max * groups / f).clamp(1, groups);
    while g > 1 && pick(g).map(size).sum::<usize>() > max {
        g -= 1;
    }
    let kept: Vec<usize> = pick(g)
        .flat_map(|k| order[starts[k]..starts[k + 1]].iter().copied())
        .collect();
    if kept.len() <= max {
        return kept;
    }
    (0..max).map(|j| kept[j * kept.len() / max]).collect()
}

/// Per-Gaussian, per-frame observations `x = f/z` (0 = not visible / not recorded).
/// Layout: Gaussian-major, `slots[n * F + f]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ObservationTable {
    times: Vec<f32>,
    slots: Vec<f32>,
    rows: usize,
}

/// Training frames grouped by normalised time (all cameras of a multi-view
/// timestamp share one group), the grouping both estimators of nu(t) start from.
pub(crate) struct TimeGroups {
    /// Frame indices sorted by time; group `g` is `frames[start[g]..start[g + 1]]`.
    pub frames: Vec<u32>,
    /// Group starts, then `frames.len()`.
    pub start: Vec<usize>,
    /// Normalised time of each group, increasing.
    pub times: Vec<f32>,
}

impl TimeGroups {
    /// Groups frames with the given times (in `cfg.time_range`).
    pub fn new(times: &[f32], cfg: &FilterConfig) -> TimeGroups {
        let tn: Vec<f32> = times.iter().map(|&t| cfg.normalise_time(t)).collect();
        let mut frames: Vec<u32> = (0..times.len() as u32).collect();
        frames.sort_by(|&a, &b| tn[a as usize].total_cmp(&tn[b as usize]));
        let (mut start, mut group_times) = (Vec::new(), Vec::<f32>::new());
        for (i, &f) in frames.iter().enumerate() {
            let t = tn[f as usize];
            if group_times.last() != Some(&t) {
                start.push(i);
                group_times.push(t);
            }
        }
        start.push(frames.len());
        TimeGroups {
            frames,
            start,
            times: group_times,
        }
    }

    /// Number of groups.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Frames of group `g`.
    pub fn group(&self, g: usize) -> &[u32] {
        &self.frames[self.start[g]..self.start[g + 1]]
    }
}

impl ObservationTable {
    /// An empty table for `rows` Gaussians and the training frames with the given
    /// times (frame `f` has time `frame_times[f]`).
    pub fn new(frame_times: Vec<f32>, rows: usize) -> ObservationTable {
        let slots = vec![0.0; rows * frame_times.len()];
        ObservationTable {
            times: frame_times,
            slots,
            rows,
        }
    }

    /// An empty table for `rows` Gaussians and the given training frames.
    pub fn for_frames(frames: &[CameraTime], rows: usize) -> ObservationTable {
        Self::new(frames.iter().map(|f| f.time).collect(), rows)
    }

    /// Number of training frames F.
    pub fn num_frames(&self) -> usize {
        self.times.len()
    }

    /// CameraTime times.
    pub fn times(&self) -> &[f32] {
        &self.times
    }

    /// Observation row of Gaussian `n` (length F, 0 = empty).
    pub fn row(&self, n: usize) -> &[f32] {
        let f = self.times.len();
        &self.slots[n * f..(n + 1) * f]
    }

    /// Mutable observation row of Gaussian `n`.
    pub fn row_mut(&mut self, n: usize) -> &mut [f32] {
        let f = self.times.len();
        &mut self.slots[n * f..(n + 1) * f]
    }

    /// Observations of Gaussian `n` as `(t_j, x_j)` pairs (non-empty slots only).
    pub fn observations(&self, n: usize) -> Vec<(f32, f32)> {
        self.row(n)
            .iter()
            .zip(&self.times)
            .filter(|(x, _)| **x > 0.0)
            .map(|(&x, &t)| (t, x))
            .collect()
    }

    /// Heap bytes held by the slots (`4 F` bytes per Gaussian).
    pub fn bytes(&self) -> usize {
        self.slots.len() * std::mem::size_of::<f32>() + self.times.len() * 4
    }

    /// Full observation pass: for every distinct training time `t`, calls
    /// `centres_at(t)` once (the deformed centres of all Gaussians at `t`, length
    /// `rows`) and records `x = f/z` for every training frame at that time (Mip rule
    /// visibility). Overwrites every slot. `cameras[frame.camera]` must exist.
    pub fn observe_all<C>(
        &mut self,
        frames: &[CameraTime],
        cameras: &[Camera],
        cfg: &FilterConfig,
        mut centres_at: C,
    ) -> Result<(), FilterError>
    where
        C: FnMut(f32) -> Vec<[f32; 3]>,
    {
        if frames.len() != self.times.len() {
            return Err(FilterError::Shape(format!(
                "observe_all: {} frames given, table has {}",
                frames.len(),
                self.times.len()
            )));
        }
        let viewers = frame_viewers(frames, cameras, cfg)?;
        // Frames grouped by time so the deformation runs once per distinct time.
        let mut order: Vec<usize> = (0..frames.len()).collect();
        order.sort_by(|&a, &b| frames[a].time.total_cmp(&frames[b].time));
        let mut start = 0;
        while start < order.len() {
            let t = frames[order[start]].time;
            let mut end = start + 1;
            while end < order.len() && frames[order[end]].time == t {
                end += 1;
            }
            let centres = centres_at(t);
            for &f in &order[start..end] {
                self.record_with(f, &viewers[f], &centres, None)?;
            }
            start = end;
        }
        Ok(())
    }

    /// Incremental recorder: stores `x = f/z` of the deformed `centres` (all
    /// Gaussians, as computed by the trainer's forward pass) seen by `camera` in
    /// training frame `frame`, clearing the slots of Gaussians not visible now.
    pub fn record_centres(
        &mut self,
        frame: usize,
        camera: &Camera,
        centres: &[[f32; 3]],
        cfg: &FilterConfig,
    ) -> Result<(), FilterError> {
        let viewer = Viewer::new(camera, cfg);
        self.record_with(frame, &viewer, centres, None)
    }

    /// [`Self::record_centres`] for the Gaussians with `present[n]` set; the others
    /// get an empty slot for `frame`: a 4D Gaussian that does not exist at the frame's
    /// time (its temporal opacity leaves nothing to draw) is not observed there, as
    /// Mip-Splatting's indicator `1_n(p)` counts only primitives the view can see.
    pub fn record_present(
        &mut self,
        frame: usize,
        camera: &Camera,
        centres: &[[f32; 3]],
        present: &[bool],
        cfg: &FilterConfig,
    ) -> Result<(), FilterError> {
        self.check_frame(frame, present.len())?;
        let viewer = Viewer::new(camera, cfg);
        self.record_with(frame, &viewer, centres, Some(present))
    }

    /// Low-level recorder: `depths[n]` is Gaussian `n`'s camera-space depth in frame
    /// `frame`, or any value `<= 0` / non-finite when the trainer deems it not
    /// visible; `focal` is the camera's `max(fx, fy)`. Stores `focal / depth`.
    /// Prefer [`Self::record_centres`], which applies exactly the visibility rule of
    /// the full pass.
    pub fn record_depths(
        &mut self,
        frame: usize,
        focal: f32,
        depths: &[f32],
    ) -> Result<(), FilterError> {
        self.check_frame(frame, depths.len())?;
        let f = self.times.len();
        for (n, &z) in depths.iter().enumerate() {
            self.slots[n * f + frame] = if z.is_finite() && z > 0.0 {
                focal / z
            } else {
                0.0
            };
        }
        Ok(())
    }

    fn check_frame(&self, frame: usize, len: usize) -> Result<(), FilterError> {
        if frame >= self.times.len() {
            return Err(FilterError::Shape(format!(
                "frame {frame} out of range for {} training frames",
                self.times.len()
            )));
        }
        if len != self.rows {
            return Err(FilterError::Shape(format!(
                "{len} Gaussians given, the observation table has {}",
                self.rows
            )));
        }
        Ok(())
    }

    fn record_with(
        &mut self,
        frame: usize,
        viewer: &Viewer,
        centres: &[[f32; 3]],
        present: Option<&[bool]>,
    ) -> Result<(), FilterError> {
        self.check_frame(frame, centres.len())?;
        let f = self.times.len();
        if f == 0 {
            return Ok(());
        }
        // Parallel over Gaussians: each writes its own row's slot `frame`.
        self.slots
            .par_chunks_mut(f)
            .zip(centres.par_iter())
            .enumerate()
            .for_each(|(n, (row, &p))| {
                let seen = present.is_none_or(|m| m[n]);
                row[frame] = if seen {
                    viewer.sampling_rate(p).unwrap_or(0.0)
                } else {
                    0.0
                };
            });
        Ok(())
    }
}

fn frame_viewers(
    frames: &[CameraTime],
    cameras: &[Camera],
    cfg: &FilterConfig,
) -> Result<Vec<Viewer>, FilterError> {
    frames
        .iter()
        .map(|fr| {
            cameras
                .get(fr.camera)
                .map(|c| Viewer::new(c, cfg))
                .ok_or_else(|| {
                    FilterError::Shape(format!(
                        "frame camera index {} out of range for {} cameras",
                        fr.camera,
                        cameras.len()
                    ))
                })
        })
        .collect()
}

impl PerGaussian for ObservationTable {
    fn rows(&self) -> usize {
        self.rows
    }

    /// Clone/split copy a Gaussian's observations, prune drops them (the copies are
    /// exact until the next refresh; Mip-Splatting also recomputes after densifying).
    fn select_rows(&mut self, index: &[usize]) {
        let f = self.times.len();
        let mut slots = Vec::with_capacity(index.len() * f);
        for &i in index {
            assert!(
                i < self.rows,
                "select_rows: index {i} out of range for {} rows",
                self.rows
            );
            slots.extend_from_slice(&self.slots[i * f..(i + 1) * f]);
        }
        self.slots = slots;
        self.rows = index.len();
    }
}
