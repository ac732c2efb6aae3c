//! Dynamic 3D Gaussians' tracking (Luiten et al., 3DV 2024; code
//! JonathonLuiten/Dynamic3DGaussians `train.py`, `loss.py`, `helpers.py`,
//! `external.py`): Gaussians that move, frame by frame.
//!
//! Every Gaussian has a centre `mu_k` and a quaternion `q_k` per frame `k` (the
//! distinct training times in order); its colour (RGB, or SH with `sh_degree` > 0),
//! log-scales and opacity logit are shared by every frame. Frame 0 is trained first,
//! as a static 3DGS scene with densification (`first_frame_iterations` of the run);
//! then each later frame in turn, one random training view of its time per
//! iteration ([`TrainingHooks::training_time`]). The current frame's centres and
//! quaternions are the canonical 3DGS tensors `xyz` and `rotation` of the store, so
//! densification, the opacity reset, the 3D filter and the optimiser see them
//! unchanged; a finished frame's are kept as constants ([`Frame`], carried in
//! checkpoints as buffers).
//!
//! **Switching to frame k > 0** ([`Representation::set_iteration`] at the frame's
//! first iteration): frame k - 1 is stored, and frame k starts at the constant-velocity
//! guess `mu_k = mu_k-1 + (mu_k-1 - mu_k-2)`, `q_k = normalise(q_k-1 + (q_k-1 -
//! q_k-2))` (unit quaternions; for k = 1 frame k - 2 is frame 0 itself: no velocity);
//! the Adam moments of `xyz` and `rotation` restart ([`TrainingHooks::reset_moments`]).
//! At the first switch each Gaussian's `knn` nearest neighbours `j` on the frame-0
//! centres are found once, with weights `w_ij = exp(-neighbour_falloff |mu_j0 -
//! mu_i0|^2)` ([`Neighbours`]). Opacity and log-scales are frozen from then on
//! (learning rate 0, `LrSchedule::Until`); the colour keeps its rate.
//!
//! **Regularisers of frame k > 0** (`loss.py`; the previous frame's values are
//! constants), each a term of the objective under its name with its weight:
//! - `rigidity` (4): `mean_ij sqrt(w_ij |R_i^T (mu_j - mu_i) - (mu'_j - mu'_i)|^2 +
//!   1e-20)`, `R_i` the rotation of `q_i / |q_i| conj(p_i)` ([`Rigidity`]);
//! - `rotation` (4): `mean_ij sqrt(w_ij |r_j - r_i|^2 + 1e-20)`, `r_i = q_i / |q_i|
//!   conj(p_i)` ([`Similarity`]);
//! - `isometry` (2): `mean_ij sqrt(w_ij (|mu_j - mu_i| - |mu_j0 - mu_i0|)^2 + 1e-20)`
//!   ([`Isometry`]);
//! - `colour_consistency` (0.01): `mean_i sum_c |col_i - col'_i|`, `col'` the colours
//!   at the switch to frame k;
//!
//! with `mu'`, `p` the previous frame's centres and unit quaternions. The reference's
//! floor and background terms are data-set specific and left out; every Gaussian is
//! tracked.
//!
//! **Rendering at time t** ([`TrackBound`]): at a frame's time that frame; between
//! two trained frames the centres interpolated linearly and the quaternions by
//! normalised linear interpolation; before the first frame or after the current one,
//! clamped to it.

mod bound;
mod config;
mod frames;
mod hooks;
mod isometry;
mod neighbours;
mod quat;
mod rigidity;
mod schedule;
mod similarity;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_ops;

use std::sync::Arc;

use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, Tensor};

use super::{
    Bound, CanonicalIds, InitialGaussians, ModelInit, PointCloud, Representation, TrainingHooks,
};
use crate::params::{BoundParams, ParamId, ParamStore, Rows};

pub use bound::TrackBound;
pub use config::{TrackConfig, TrackLr};
pub use frames::Frame;
pub use isometry::Isometry;
pub use neighbours::Neighbours;
pub use rigidity::Rigidity;
pub use schedule::FrameSchedule;
pub use similarity::Similarity;

/// Name of the local-rigidity regulariser.
pub const RIGIDITY: &str = "rigidity";
/// Name of the rotation-similarity regulariser.
pub const ROTATION: &str = "rotation";
/// Name of the isometry regulariser.
pub const ISOMETRY: &str = "isometry";
/// Name of the colour-consistency regulariser.
pub const COLOUR: &str = "colour_consistency";

/// Where each parameter sits in the store.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackIds {
    /// The current frame's centres \[N,3].
    pub xyz: ParamId,
    /// Log-scales \[N,3].
    pub log_scale: ParamId,
    /// The current frame's quaternions \[N,4] (w, x, y, z), unnormalised.
    pub rotation: ParamId,
    /// Opacity logits \[N].
    pub opacity: ParamId,
    /// Colours \[N,3] (RGB: the SH DC band is `(rgb - 0.5) / C0`).
    pub rgb: ParamId,
    /// Higher SH bands \[N,K-1,3], absent at degree 0.
    pub sh_rest: Option<ParamId>,
}

/// The tracking model: parameters, the frame schedule, the finished frames and the
/// neighbour pairs.
#[derive(Clone, Debug)]
pub struct TrackModel<T: Float> {
    /// Configuration.
    pub config: TrackConfig,
    /// Every trainable tensor.
    pub params: ParamStore<T>,
    /// Where each one is.
    pub ids: TrackIds,
    schedule: FrameSchedule,
    /// Frames 0..c-1 (c the current frame), in order.
    finished: Vec<Arc<Frame<T>>>,
    /// The colours at the switch to the current frame (none in frame 0).
    previous_colour: Option<Arc<Tensor<T>>>,
    /// The neighbour pairs on frame 0's centres (none in frame 0).
    neighbours: Option<Arc<Neighbours>>,
    /// Buffers of a checkpoint, kept until all of them have arrived.
    pending: Vec<(String, Tensor<T>)>,
}

impl<T: Float> TrackModel<T> {
    /// A model of `init`: the frames are its training times over its
    /// `iterations` ([`FrameSchedule`]); the Gaussians start from the points of the
    /// first frame ([`first_frame_points`]) as 3DGS `create_from_pcd` does, but with
    /// opacity 0.5 (the reference's logit 0) and the colour as RGB. An error names the
    /// key when a later frame would get no iteration.
    pub fn new(config: TrackConfig, init: &ModelInit) -> Result<Self, String> {
        config.validate()?;
        let schedule = FrameSchedule::new(
            init.times.clone(),
            init.iterations,
            config.first_frame_iterations,
        )?;
        let cloud = first_frame_points(&init.cloud, &init.times);
        let g = InitialGaussians::<T>::from_cloud(&cloud, config.sh_coeffs());
        let n = cloud.len();
        let rgb = cloud.colours.iter().flatten().map(|&c| T::of(c)).collect();
        let lr = &config.lr;
        let frozen = |rate: f64| LrSchedule::Until {
            lr: rate,
            until: schedule.first_end(),
        };
        let mut p = ParamStore::new();
        let mut pg =
            |name: &str, t: Tensor<T>, lr: LrSchedule| p.add(name, t, Rows::PerGaussian, lr, 0.0);
        let ids = TrackIds {
            xyz: pg(
                "xyz",
                g.xyz,
                LrSchedule::Constant(lr.position * init.extent),
            ),
            log_scale: pg("log_scale", g.log_scale, frozen(lr.scaling)),
            rotation: pg("rotation", g.rotation, LrSchedule::Constant(lr.rotation)),
            opacity: pg("opacity", Tensor::zeros(&[n]), frozen(lr.opacity)),
            rgb: pg(
                "rgb",
                Tensor::from_vec(rgb, &[n, 3]),
                LrSchedule::Constant(lr.colour),
            ),
            sh_rest: (config.sh_degree > 0)
                .then(|| pg("sh_rest", g.sh_rest, LrSchedule::Constant(lr.colour / 20.0))),
        };
        Ok(TrackModel {
            config,
            params: p,
            ids,
            schedule,
            finished: Vec::new(),
            previous_colour: None,
            neighbours: None,
            pending: Vec::new(),
        })
    }

    /// The frame whose variables the store holds (0-based).
    pub fn current_frame(&self) -> usize {
        self.finished.len()
    }

    /// The neighbour pairs (found at the first switch).
    pub fn neighbours(&self) -> Option<&Neighbours> {
        self.neighbours.as_deref()
    }

    /// Binds on the tape of `params` with the concrete type.
    pub fn bind_track<'t>(&self, params: &BoundParams<'t, T>) -> TrackBound<'t, T> {
        TrackBound::new(self, params)
    }

    /// Finishes the current frame and starts the next from the constant-velocity
    /// guess (module docs); the neighbours are found at the first switch.
    fn advance(&mut self) {
        let p = &self.params;
        let done = Frame::new(p.value(self.ids.xyz).clone(), p.value(self.ids.rotation));
        if self.finished.is_empty() {
            self.neighbours = Some(Arc::new(self.find_neighbours(&done)));
        }
        let next = done.extrapolate(self.finished.last().map_or(&done, |f| f));
        self.previous_colour = Some(Arc::new(p.value(self.ids.rgb).clone()));
        self.finished.push(Arc::new(done));
        *self.params.value_mut(self.ids.xyz) = next.means;
        *self.params.value_mut(self.ids.rotation) = next.quats;
    }

    /// The neighbour pairs on `frame`'s centres.
    fn find_neighbours(&self, frame: &Frame<T>) -> Neighbours {
        let points: Vec<[f64; 3]> = frame
            .means
            .data()
            .chunks_exact(3)
            .map(|c| std::array::from_fn(|a| c[a].to_f64()))
            .collect();
        Neighbours::new(&points, self.config.knn, self.config.neighbour_falloff)
    }
}

/// The points a tracking model starts from: when the cloud has times, those of the
/// earliest training frame it has points at, plus those whose time is no training
/// frame's (the random static points of the visual-hull cloud); without times, or
/// with a single training time, all of them. A point is at a frame when its time is
/// within a thousandth of the smallest frame spacing of the frame's time (clouds store
/// times as f32).
pub fn first_frame_points(cloud: &PointCloud, times: &[f64]) -> PointCloud {
    let Some(point_times) = cloud.times.as_ref().filter(|_| times.len() > 1) else {
        return cloud.clone();
    };
    let gap = times
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    let frame_of = |t: f64| {
        let f = times.partition_point(|&x| x < t);
        [f.checked_sub(1), Some(f)]
            .into_iter()
            .flatten()
            .filter(|&f| f < times.len())
            .find(|&f| (times[f] - t).abs() <= 1e-3 * gap)
    };
    let frames: Vec<Option<usize>> = point_times.iter().map(|&t| frame_of(t)).collect();
    let Some(first) = frames.iter().flatten().min().copied() else {
        return cloud.clone();
    };
    let keep: Vec<usize> = (0..cloud.len())
        .filter(|&i| frames[i].is_none_or(|f| f == first))
        .collect();
    PointCloud {
        points: keep.iter().map(|&i| cloud.points[i]).collect(),
        colours: keep.iter().map(|&i| cloud.colours[i]).collect(),
        times: Some(keep.iter().map(|&i| point_times[i]).collect()),
    }
}

impl<T: Float> Representation<T> for TrackModel<T> {
    fn name(&self) -> &str {
        "track"
    }

    fn params(&self) -> &ParamStore<T> {
        &self.params
    }

    fn params_mut(&mut self) -> &mut ParamStore<T> {
        &mut self.params
    }

    fn canonical_ids(&self) -> CanonicalIds {
        CanonicalIds {
            means: self.ids.xyz,
            log_scales: self.ids.log_scale,
            quats: self.ids.rotation,
            opacity_logits: self.ids.opacity,
        }
    }

    fn bind<'t>(&self, params: &BoundParams<'t, T>) -> Box<dyn Bound<'t, T> + 't> {
        Box::new(self.bind_track(params))
    }

    /// `rigidity`, `rotation`, `isometry` and `colour_consistency` with their weights
    /// (`loss.py` `LOSS_WEIGTHS`); 0 in frame 0.
    fn regularisers(&self) -> Vec<(String, f64)> {
        let c = &self.config;
        vec![
            (RIGIDITY.into(), c.rigidity),
            (ROTATION.into(), c.rotation),
            (ISOMETRY.into(), c.isometry),
            (COLOUR.into(), c.colour_consistency),
        ]
    }

    /// Moves on to the frame the schedule gives `iteration` (never back: a model
    /// loaded past it stays at its frame), one switch at a time (module docs).
    fn set_iteration(&mut self, iteration: usize) {
        while self.finished.len() < self.schedule.frame_of(iteration) {
            self.advance();
        }
    }

    /// The finished frames, the frame schedule and the Adam restarts
    /// ([`TrainingHooks`]).
    fn hooks(&self) -> Option<&dyn TrainingHooks<T>> {
        Some(self)
    }

    fn hooks_mut(&mut self) -> Option<&mut dyn TrainingHooks<T>> {
        Some(self)
    }
}
