//! A tracking model bound on a tape: the Gaussians at any time from the current
//! frame's variables and the finished frames' constants, and the regularisers of the
//! current frame (module docs of [`super`] give the formulas).

use std::cell::OnceCell;
use std::sync::Arc;

use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Tensor, Var};
use maaf_splat::GaussianVars;
use maaf_splat::sh::SH_C0;

use super::frames::{At, Frame, locate};
use super::isometry::Isometry;
use super::neighbours::Neighbours;
use super::rigidity::Rigidity;
use super::similarity::Similarity;
use super::{COLOUR, ISOMETRY, RIGIDITY, ROTATION, TrackModel};
use crate::Bound;
use crate::params::BoundParams;

/// A tracking model bound on a tape (see [`Bound`]).
pub struct TrackBound<'t, T: Float> {
    /// The current frame's centres and (unnormalised) quaternions.
    means: Var<'t, T>,
    quats: Var<'t, T>,
    scales: Var<'t, T>,
    opacity: Var<'t, T>,
    rgb: Var<'t, T>,
    sh: Var<'t, T>,
    /// Times of the finished frames and then the current one.
    times: Vec<f64>,
    finished: Vec<Arc<Frame<T>>>,
    neighbours: Option<Arc<Neighbours>>,
    previous_colour: Option<Arc<Tensor<T>>>,
    /// The regularisers, computed at their first request (every view of a step asks).
    terms: OnceCell<Vec<(String, Var<'t, T>)>>,
    #[cfg(test)]
    pub(super) faults: [bool; 3],
}

impl<'t, T: Float> TrackBound<'t, T> {
    /// Binds `model` on the tape of `params`.
    pub fn new(model: &TrackModel<T>, params: &BoundParams<'t, T>) -> Self {
        let ids = &model.ids;
        let rgb = params.get(ids.rgb);
        let n = rgb.value().rows();
        let dc = rgb.add_scalar(-0.5).scale(1.0 / SH_C0).reshape(&[n, 1, 3]);
        let sh = match ids.sh_rest {
            Some(rest) => concat(&[dc, params.get(rest)], 1),
            None => dc,
        };
        let current = model.finished.len();
        TrackBound {
            means: params.get(ids.xyz),
            quats: params.get(ids.rotation),
            scales: params.get(ids.log_scale).exp(),
            opacity: params.get(ids.opacity).sigmoid(),
            rgb,
            sh,
            times: model.schedule.times()[..=current].to_vec(),
            finished: model.finished.clone(),
            neighbours: model.neighbours.clone(),
            previous_colour: model.previous_colour.clone(),
            terms: OnceCell::new(),
            #[cfg(test)]
            faults: [false; 3],
        }
    }

    fn constant(&self, t: Tensor<T>) -> Var<'t, T> {
        self.means.tape().constant(t)
    }

    /// Centres and quaternions of frame `f`.
    fn frame(&self, f: usize) -> (Var<'t, T>, Var<'t, T>) {
        match self.finished.get(f) {
            Some(frame) => (
                self.constant(frame.means.clone()),
                self.constant(frame.quats.clone()),
            ),
            None => (self.means, self.quats),
        }
    }

    /// A fraction `a` of the way from frame `f` (finished) to frame `f + 1`: centres
    /// `(1 - a) mu_f + a mu_f+1`, quaternions `(1 - a) q_f + a s q_f+1` with unit
    /// `q` and `s = sign(q_f . q_f+1)` per Gaussian (the shorter arc; the renderer
    /// normalises, so this is normalised linear interpolation).
    fn between(&self, f: usize, a: f64) -> (Var<'t, T>, Var<'t, T>) {
        let from = &self.finished[f];
        let (to_means, to_quats) = match self.finished.get(f + 1) {
            Some(to) => (
                self.constant(to.means.clone()),
                self.constant(to.quats.clone()),
            ),
            None => {
                let q = self.quats;
                let n = q.value().rows();
                (
                    self.means,
                    q / q.square().sum_axis(1).sqrt().reshape(&[n, 1]),
                )
            }
        };
        let signs: Vec<T> = from
            .quats
            .data()
            .chunks_exact(4)
            .zip(to_quats.value().data().chunks_exact(4))
            .map(|(p, q)| {
                let dot = p.iter().zip(q).fold(T::zero(), |s, (&x, &y)| s + x * y);
                T::of(if dot < T::zero() { -a } else { a })
            })
            .collect();
        let n = signs.len();
        let keep = |t: &Tensor<T>| self.constant(t.map(|v| v * T::of(1.0 - a)));
        (
            keep(&from.means) + to_means.scale(a),
            keep(&from.quats) + to_quats * self.constant(Tensor::from_vec(signs, &[n, 1])),
        )
    }

    /// The four regularisers of the current frame (none in frame 0).
    fn compute_terms(&self) -> Vec<(String, Var<'t, T>)> {
        let (Some(previous), Some(colour)) = (self.finished.last(), &self.previous_colour) else {
            return Vec::new();
        };
        let tape = self.means.tape();
        let drift = self.rgb - self.constant((**colour).clone());
        let mut terms = vec![(COLOUR.to_string(), drift.abs().sum_axis(1).mean())];
        if let Some(nb) = &self.neighbours {
            let rigid = Rigidity::new(nb.clone(), previous.clone());
            let similar = Similarity::new(nb.clone(), previous.clone());
            let iso = Isometry::new(nb.clone());
            #[cfg(test)]
            let (rigid, similar, iso) = (
                rigid.faulty(self.faults[0]),
                similar.faulty(self.faults[1]),
                iso.faulty(self.faults[2]),
            );
            terms.extend([
                (
                    RIGIDITY.to_string(),
                    tape.apply1(rigid, &[self.means, self.quats]),
                ),
                (ROTATION.to_string(), tape.apply1(similar, &[self.quats])),
                (ISOMETRY.to_string(), tape.apply1(iso, &[self.means])),
            ]);
        }
        terms
    }
}

impl<'t, T: Float> Bound<'t, T> for TrackBound<'t, T> {
    /// At the current frame's time its variables; at a finished frame's time its
    /// constants; between two frames [`TrackBound::between`]; before the first
    /// frame or after the current one, clamped to it. Scales, opacity and colour are
    /// shared by every frame.
    fn deform(&self, time: f64) -> GaussianVars<'t, T> {
        let (means, quats) = match locate(&self.times, time) {
            At::Frame(f) => self.frame(f),
            At::Between(f, a) => self.between(f, a),
        };
        GaussianVars {
            means,
            scales: self.scales,
            quats,
            opacity: self.opacity,
            sh: self.sh,
        }
    }

    fn regularisers(&self) -> Vec<(String, Var<'t, T>)> {
        self.terms.get_or_init(|| self.compute_terms()).clone()
    }
}
