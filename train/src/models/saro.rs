//! SaRO-GS (Yan et al., ACM MM 2024; code yjb6/SaRO-GS `scene/saro_gaussian.py`), the
//! base 4D representation of the paper (Sec. 3.2).
//!
//! Each Gaussian is a 3D Gaussian (centre, log-scale, quaternion, opacity logit, SH)
//! plus a temporal centre mu_t. At time t (`get_deformation`):
//!
//! - field features `f = F(sg(x), sg(mu_t), sg(s))` from the scale-aware K-plane field
//!   ([`super::kplane`]), `sg` = stop-gradient;
//! - lifespan `l = (1 - m)(1 - sigmoid(MLP_l(f))) + m`, `m = min_interval / duration`;
//! - `Dt = t - mu_t`, input `h = \[f, sg(PE(Dt))]`, PE = NeRF embedding with the
//!   identity and `sin, cos(2^k Dt)`, k < 4 (9 values);
//! - `mu(t) = x + MLP_x(h)`, `\[dq, ds] = MLP_r(h)`, `q(t) = q + dq` (normalised by the
//!   renderer), `s(t) = exp(log s + ds)`, `SH(t) = SH + MLP_sh(h)` (optional);
//! - opacity `sigmoid(o) * exp(-4 (Dt / l)^2)` (the code's "Eq 9").
//!
//! `L_SR = || ds at Dt = 0 ||_2` over all N x 3 entries, not squared, not averaged
//! (`helper_train.py`, `torch.linalg.vector_norm`), weight 8e-6. The residual heads
//! start at zero (DESIGN.md section 5), so at step 0 the deformed scene is the
//! canonical one with the temporal opacity factor. For the first `static_iterations`
//! the model renders plain 3D Gaussians (no field, no MLP, no temporal opacity).

use std::sync::Arc;

use maaf_autodiff::nn::{Mlp, MlpVars};
use maaf_autodiff::op::{BackwardCtx, Op};
use maaf_autodiff::ops::concat;
use maaf_autodiff::optim::LrSchedule;
use maaf_autodiff::{Float, PerGaussian, Tape, Tensor, Var};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

use super::kplane::{FieldQuery, KPlaneConfig, KPlaneField, PLANE_NAMES, PlaneSample};
use super::{
    Bound, Canonical, DeformedGaussians, ParamSlot, PointCloud, Regulariser, Representation,
    knn_mean_sq_dist, logit, rgb_to_sh_dc,
};

/// Learning rates of SaRO-GS for D-NeRF (`arguments/__init__.py`, `configs/dnerf/*.json`,
/// `SaROGaussian.training_setup` / `update_learning_rate`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SaroLr {
    /// Centres at iteration 0, times the scene extent (1.6e-4).
    pub position_init: f64,
    /// Centres at the end of the decay, times the scene extent (1.6e-6).
    pub position_final: f64,
    /// Length of every decay (`position_lr_max_steps` = 30 000).
    pub max_steps: usize,
    /// SH DC (2.5e-3); the rest uses `feature / 20`.
    pub feature: f64,
    /// Opacity logit (0.05).
    pub opacity: f64,
    /// Log-scale (3e-3 in the D-NeRF configs).
    pub scaling: f64,
    /// Quaternion (1e-3).
    pub rotation: f64,
    /// Temporal centre (`trbfc_lr` 1e-6).
    pub t_centre: f64,
    /// MLPs, start (1.6e-4).
    pub mlp_init: f64,
    /// MLPs, end (1.6e-7).
    pub mlp_final: f64,
    /// Planes, start (3.2e-3). The reference's schedule is not scaled by the extent
    /// (`update_learning_rate` overrides the extent-scaled initial value every step).
    pub plane_init: f64,
    /// Planes, end (3.2e-6).
    pub plane_final: f64,
    /// Adam L2 weight decay on MLPs and planes (8e-7).
    pub weight_decay: f64,
}

impl Default for SaroLr {
    fn default() -> Self {
        SaroLr {
            position_init: 1.6e-4,
            position_final: 1.6e-6,
            max_steps: 30_000,
            feature: 2.5e-3,
            opacity: 0.05,
            scaling: 3e-3,
            rotation: 1e-3,
            t_centre: 1e-6,
            mlp_init: 1.6e-4,
            mlp_final: 1.6e-7,
            plane_init: 3.2e-3,
            plane_final: 3.2e-6,
            weight_decay: 8e-7,
        }
    }
}

/// Configuration of the SaRO representation (a serde struct; missing fields take the
/// defaults).
///
/// CPU defaults vs SaRO-GS D-NeRF: MLP hidden width 64 (reference 128), time texels 64
/// (reference 128), 32 channels and 64 x 64 spatial planes as the reference, SH degree
/// 3 with the SH residual head as the reference. The MLPs dominate the cost (see
/// `cost_report` in the tests), and halving the width cuts it about 3x.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SaroConfig {
    /// Residual field sizes.
    pub field: KPlaneConfig,
    /// Hidden width H of the residual MLPs (two hidden layers each; the lifespan MLP
    /// uses H and H/2).
    pub hidden: usize,
    /// Frequencies of the time embedding (`deform_time_encode` = 4 -> 9 inputs).
    pub time_freqs: usize,
    /// SH degree (0..=3); K = (degree + 1)^2 coefficients per colour channel.
    pub sh_degree: usize,
    /// Predict an SH residual (`dsh: true` in the D-NeRF configs).
    pub sh_residual: bool,
    /// Shortest lifespan in frames (`min_interval` 0.5).
    pub min_interval: f64,
    /// Frames of the sequence (`duration`; mutant 150): `m = min_interval / duration`.
    pub duration: f64,
    /// Temporal-integral prune threshold (`min_intergral` 0.0025).
    pub min_integral: f64,
    /// Iterations rendered as static 3D Gaussians (`static_iteration` 1000).
    pub static_iterations: usize,
    /// Weight of L_SR (`lambda_dscale_reg` 8e-6).
    pub lambda_sr: f64,
    /// Learning rates.
    pub lr: SaroLr,
}

impl Default for SaroConfig {
    fn default() -> Self {
        SaroConfig {
            field: KPlaneConfig::default(),
            hidden: 64,
            time_freqs: 4,
            sh_degree: 3,
            sh_residual: true,
            min_interval: 0.5,
            duration: 150.0,
            min_integral: 0.0025,
            static_iterations: 1000,
            lambda_sr: 8e-6,
            lr: SaroLr::default(),
        }
    }
}

impl SaroConfig {
    /// SH coefficients per colour channel, `(degree + 1)^2`.
    pub fn sh_coeffs(&self) -> usize {
        (self.sh_degree + 1) * (self.sh_degree + 1)
    }

    /// Width of the time embedding: `1 + 2 * time_freqs`.
    pub fn pe_dim(&self) -> usize {
        1 + 2 * self.time_freqs
    }

    /// Shortest lifespan `m = min_interval / duration`.
    pub fn min_lifespan(&self) -> f64 {
        self.min_interval / self.duration.max(1.0)
    }
}

/// The SaRO-GS model: per-Gaussian tensors, the residual field and the MLPs.
#[derive(Clone, Debug)]
pub struct SaroModel<T: Float> {
    /// Configuration.
    pub config: SaroConfig,
    /// Scene extent: scales the position learning rate (3DGS `spatial_lr_scale`).
    pub scene_extent: f64,
    /// Canonical centres \[N,3] (`_xyz`).
    pub xyz: Tensor<T>,
    /// Log-scales \[N,3] (`_scaling`).
    pub log_scale: Tensor<T>,
    /// Quaternions \[N,4], w,x,y,z, unnormalised (`_rotation`).
    pub rotation: Tensor<T>,
    /// Opacity logits \[N] (`_opacity`).
    pub opacity: Tensor<T>,
    /// SH DC \[N,1,3] (`_features_dc`).
    pub sh_dc: Tensor<T>,
    /// Higher SH bands \[N,K-1,3] (`_features_rest`).
    pub sh_rest: Tensor<T>,
    /// Temporal centres \[N] (`_temporal_pos`, not squashed: `sigmoid_tcenter` false).
    pub t_centre: Tensor<T>,
    /// Scale-aware residual field.
    pub field: KPlaneField<T>,
    /// `motion_mlp`: \[f, PE] -> dx (3).
    pub motion_mlp: Mlp<T>,
    /// `rot_mlp`: \[f, PE] -> dq (4), d log s (3).
    pub rot_mlp: Mlp<T>,
    /// `shs_mlp`: \[f, PE] -> dSH (3K), when `sh_residual`.
    pub sh_mlp: Option<Mlp<T>>,
    /// `opacity_mlp`: f -> lifespan logit (1).
    pub life_mlp: Mlp<T>,
    dynamic: bool,
    /// Test-only: bind the field with a deliberately wrong backward (negative control).
    #[cfg_attr(not(test), allow(dead_code))]
    corrupt_field_backward: bool,
}

/// Stop-gradient inputs of one bind: the field query and the temporal centres used in
/// the time embedding. In training they are read from the parameters; a gradient
/// check keeps them fixed while the parameters move (that is what "detached" means).
#[derive(Clone, Debug)]
pub struct Detached {
    /// Field query from sg(x), sg(mu_t), sg(exp(log s)).
    pub query: Arc<FieldQuery>,
    /// sg(mu_t) per Gaussian.
    pub t_centre: Arc<Vec<f64>>,
}

/// A SaRO model bound on a tape (see [`Bound`]).
pub struct SaroBound<'t, T: Float> {
    n: usize,
    k: usize,
    time_freqs: usize,
    xyz: Var<'t, T>,
    log_scale: Var<'t, T>,
    rotation: Var<'t, T>,
    opacity: Var<'t, T>,
    sh: Var<'t, T>,
    dynamic: Option<DynamicVars<'t, T>>,
}

struct DynamicVars<'t, T: Float> {
    t_centre: Var<'t, T>,
    features: Var<'t, T>,
    lifespan: Var<'t, T>,
    t_centre_detached: Arc<Vec<f64>>,
    motion: MlpVars<'t, T>,
    rot: MlpVars<'t, T>,
    sh: Option<MlpVars<'t, T>>,
    l_sr: Var<'t, T>,
    lambda_sr: f64,
}

/// `\[d, sin(2^0 d), cos(2^0 d), ..., sin(2^(F-1) d), cos(2^(F-1) d)]` per row (NeRF
/// embedder with `include_input`, log sampling; SaRO-GS `get_embedder`), as a constant.
fn time_embedding<T: Float>(d: impl ExactSizeIterator<Item = f64>, freqs: usize) -> Tensor<T> {
    let n = d.len();
    let w = 1 + 2 * freqs;
    let mut out = Vec::with_capacity(n * w);
    for d in d {
        out.push(T::of(d));
        for k in 0..freqs {
            let a = d * (1u64 << k) as f64;
            out.push(T::of(a.sin()));
            out.push(T::of(a.cos()));
        }
    }
    Tensor::from_vec(out, &[n, w])
}

impl<'t, T: Float> SaroBound<'t, T> {
    /// Lifespans l \[N] (None in the static stage).
    pub fn lifespan(&self) -> Option<Var<'t, T>> {
        self.dynamic.as_ref().map(|d| d.lifespan)
    }

    /// Field features \[N, C] (None in the static stage).
    pub fn features(&self) -> Option<Var<'t, T>> {
        self.dynamic.as_ref().map(|d| d.features)
    }

    /// `L_SR` (None in the static stage).
    pub fn l_sr(&self) -> Option<Var<'t, T>> {
        self.dynamic.as_ref().map(|d| d.l_sr)
    }
}

impl<'t, T: Float> Bound<'t, T> for SaroBound<'t, T> {
    fn deform(&self, time: f64) -> DeformedGaussians<'t, T> {
        let Some(d) = &self.dynamic else {
            return DeformedGaussians {
                means: self.xyz,
                scales: self.log_scale.exp(),
                quats: self.rotation,
                opacity: self.opacity,
                sh: self.sh,
            };
        };
        let tape = self.xyz.tape();
        let pe = time_embedding::<T>(
            d.t_centre_detached.iter().map(|&m| time - m),
            self.time_freqs,
        );
        let h = concat(&[d.features, tape.constant(pe)], 1);
        let dx = d.motion.forward(h);
        let r = d.rot.forward(h);
        let means = self.xyz + dx;
        let quats = self.rotation + r.slice(1, 0, 4);
        let scales = (self.log_scale + r.slice(1, 4, 7)).exp();
        // w(t) = exp(-4 ((t - mu_t) / l)^2), gradient to mu_t and (via l) the field.
        let dt = d.t_centre.scale(-1.0).add_scalar(time);
        let w = (dt / d.lifespan).square().scale(-4.0).exp();
        let opacity = self.opacity * w;
        let sh = match &d.sh {
            Some(m) => self.sh + m.forward(h).reshape(&[self.n, self.k, 3]),
            None => self.sh,
        };
        DeformedGaussians {
            means,
            scales,
            quats,
            opacity,
            sh,
        }
    }

    fn regularisers(&self) -> Vec<Regulariser<'t, T>> {
        match &self.dynamic {
            Some(d) => vec![Regulariser {
                name: "l_sr".into(),
                value: d.l_sr,
                default_weight: d.lambda_sr,
            }],
            None => Vec::new(),
        }
    }
}

/// `||x||_2` over all elements, with the subgradient 0 at x = 0 (as
/// `torch.linalg.vector_norm`): backward `g x / ||x||`. L_SR needs it because the
/// scale residual is exactly zero at initialisation, where `sqrt(sum x^2)` has an
/// infinite derivative.
pub struct Norm2;

impl<T: Float> Op<T> for Norm2 {
    type Saved = ();
    fn name(&self) -> String {
        "norm2".into()
    }
    fn forward(&self, x: &[&Tensor<T>]) -> (Vec<Tensor<T>>, ()) {
        let s: T = x[0].data().iter().map(|&v| v * v).sum();
        (vec![Tensor::scalar(s.sqrt())], ())
    }
    fn backward(&self, c: &BackwardCtx<'_, T, ()>) -> Vec<Option<Tensor<T>>> {
        let norm = c.outputs[0].item();
        let g = c.grad_outputs[0].item();
        let k = if norm > T::zero() {
            g / norm
        } else {
            T::zero()
        };
        vec![Some(c.inputs[0].map(|v| v * k))]
    }
}

/// The logistic function in the same stable form as the tape's `sigmoid`
/// (`1/(1+e^-x)` for x >= 0, `e^x/(1+e^x)` otherwise), so canonical and bound
/// opacities agree bit for bit.
fn sigmoid<T: Float>(x: T) -> T {
    if x >= T::zero() {
        T::one() / (T::one() + (-x).exp())
    } else {
        let e = x.exp();
        e / (T::one() + e)
    }
}

/// Handles of every parameter on one tape, in [`SaroModel::param_names`] order.
struct ParamVars<'t, T: Float> {
    xyz: Var<'t, T>,
    log_scale: Var<'t, T>,
    rotation: Var<'t, T>,
    opacity: Var<'t, T>,
    sh_dc: Var<'t, T>,
    sh_rest: Option<Var<'t, T>>,
    t_centre: Var<'t, T>,
    planes: Vec<Var<'t, T>>,
    motion: MlpVars<'t, T>,
    rot: MlpVars<'t, T>,
    sh: Option<MlpVars<'t, T>>,
    life: MlpVars<'t, T>,
}

fn mlp_vars<'t, T: Float>(
    vars: &mut impl Iterator<Item = Var<'t, T>>,
    mlp: &Mlp<T>,
) -> MlpVars<'t, T> {
    MlpVars {
        layers: mlp
            .layers
            .iter()
            .map(|_| maaf_autodiff::nn::LinearVars {
                weight: vars.next().expect("SaroModel: too few parameter vars"),
                bias: vars.next().expect("SaroModel: too few parameter vars"),
            })
            .collect(),
    }
}

impl<T: Float> SaroModel<T> {
    /// Initialises from a point cloud (SaRO-GS `create_from_pcd`): centres = points,
    /// scale = sqrt of the mean squared distance to the 3 nearest neighbours (log,
    /// clamped to \[-10, 1]), identity rotation, opacity 0.1 (as a logit), SH DC from the
    /// colour and zero higher bands, mu_t ~ U(0, 1), zero planes normalised by the
    /// cloud's bounds, residual heads zero, lifespan MLP with PyTorch's default init.
    pub fn from_point_cloud(
        cloud: &PointCloud,
        config: SaroConfig,
        scene_extent: f64,
        seed: u64,
    ) -> Self {
        let n = cloud.len();
        let k = config.sh_coeffs();
        let dist2 = knn_mean_sq_dist(&cloud.points, 3);
        let xyz = Tensor::from_vec(
            cloud.points.iter().flatten().map(|&v| T::of(v)).collect(),
            &[n, 3],
        );
        let log_scale = Tensor::from_vec(
            dist2
                .iter()
                .flat_map(|&d| [T::of((d.sqrt().ln()).clamp(-10.0, 1.0)); 3])
                .collect(),
            &[n, 3],
        );
        let rotation = Tensor::from_vec(
            (0..n)
                .flat_map(|_| [T::one(), T::zero(), T::zero(), T::zero()])
                .collect(),
            &[n, 4],
        );
        let opacity = Tensor::full(&[n], T::of(logit(0.1)));
        let sh_dc = Tensor::from_vec(
            cloud
                .colours
                .iter()
                .flatten()
                .map(|&c| T::of(rgb_to_sh_dc(c)))
                .collect(),
            &[n, 1, 3],
        );
        let sh_rest = Tensor::zeros(&[n, k - 1, 3]);
        let mut rng = Pcg64::seed_from_u64(seed);
        let t_centre = Tensor::from_vec(
            (0..n).map(|_| T::of(rng.random_range(0.0..1.0))).collect(),
            &[n],
        );
        let (lo, hi) = cloud.bounds();
        let field = KPlaneField::new(config.field.clone(), lo, hi);
        Self::assemble(
            config,
            scene_extent,
            [xyz, log_scale, rotation, opacity, sh_dc, sh_rest, t_centre],
            field,
            seed,
        )
    }

    /// Builds the model around given per-Gaussian tensors (xyz, log_scale, rotation,
    /// opacity, sh_dc, sh_rest, t_centre) and field, with fresh MLPs (zero heads).
    pub fn assemble(
        config: SaroConfig,
        scene_extent: f64,
        per_gaussian: [Tensor<T>; 7],
        field: KPlaneField<T>,
        seed: u64,
    ) -> Self {
        let [xyz, log_scale, rotation, opacity, sh_dc, sh_rest, t_centre] = per_gaussian;
        let c = config.field.channels;
        let h = config.hidden;
        let input = c + config.pe_dim();
        let k = config.sh_coeffs();
        let seed = seed.wrapping_mul(0x9E37_79B9);
        let motion_mlp = Mlp::new(&[input, h, h, 3], true, seed.wrapping_add(1));
        let rot_mlp = Mlp::new(&[input, h, h, 7], true, seed.wrapping_add(2));
        let sh_mlp = config
            .sh_residual
            .then(|| Mlp::new(&[input, h, h, 3 * k], true, seed.wrapping_add(3)));
        let life_mlp = Mlp::new(&[c, h, (h / 2).max(1), 1], false, seed.wrapping_add(4));
        SaroModel {
            config,
            scene_extent,
            xyz,
            log_scale,
            rotation,
            opacity,
            sh_dc,
            sh_rest,
            t_centre,
            field,
            motion_mlp,
            rot_mlp,
            sh_mlp,
            life_mlp,
            dynamic: false,
            corrupt_field_backward: false,
        }
    }

    /// Whether the dynamic stage (field + MLPs + temporal opacity) is on.
    pub fn is_dynamic(&self) -> bool {
        self.dynamic
    }

    /// Forces the stage (normally set by [`Representation::set_iteration`]).
    pub fn set_dynamic(&mut self, on: bool) {
        self.dynamic = on;
    }

    fn has_sh_rest(&self) -> bool {
        self.config.sh_coeffs() > 1
    }

    /// Every parameter as (name, tensor, per-Gaussian, schedule, weight decay), in the
    /// fixed order that [`SaroModel::param_tensors`] and the tape binding use.
    fn slots(&mut self) -> Vec<ParamSlot<'_, T>> {
        let lr = self.config.lr.clone();
        let ext = self.scene_extent;
        let has_rest = self.has_sh_rest();
        let decay = |init: f64, last: f64| LrSchedule::ExpDecay {
            init,
            last,
            max_steps: lr.max_steps,
        };
        let pg = |name: &str, value, lr: LrSchedule| ParamSlot {
            name: name.to_string(),
            value,
            per_gaussian: true,
            lr,
            weight_decay: 0.0,
        };
        let mut out = vec![
            pg(
                "xyz",
                &mut self.xyz,
                decay(lr.position_init * ext, lr.position_final * ext),
            ),
            pg(
                "log_scale",
                &mut self.log_scale,
                LrSchedule::Constant(lr.scaling),
            ),
            pg(
                "rotation",
                &mut self.rotation,
                LrSchedule::Constant(lr.rotation),
            ),
            pg(
                "opacity",
                &mut self.opacity,
                LrSchedule::Constant(lr.opacity),
            ),
            pg("sh_dc", &mut self.sh_dc, LrSchedule::Constant(lr.feature)),
        ];
        if has_rest {
            out.push(pg(
                "sh_rest",
                &mut self.sh_rest,
                LrSchedule::Constant(lr.feature / 20.0),
            ));
        }
        out.push(pg(
            "t_centre",
            &mut self.t_centre,
            LrSchedule::Constant(lr.t_centre),
        ));
        let shared = |name: String, value, lr: LrSchedule, wd: f64| ParamSlot {
            name,
            value,
            per_gaussian: false,
            lr,
            weight_decay: wd,
        };
        for (p, plane) in self.field.planes.iter_mut().enumerate() {
            out.push(shared(
                format!("field.{}", PLANE_NAMES[p]),
                plane,
                decay(lr.plane_init, lr.plane_final),
                lr.weight_decay,
            ));
        }
        let mut mlps: Vec<(&str, &mut Mlp<T>)> = vec![
            ("motion_mlp", &mut self.motion_mlp),
            ("rot_mlp", &mut self.rot_mlp),
        ];
        if let Some(m) = self.sh_mlp.as_mut() {
            mlps.push(("sh_mlp", m));
        }
        mlps.push(("life_mlp", &mut self.life_mlp));
        for (name, mlp) in mlps {
            for (pname, value) in mlp.params_mut(name) {
                out.push(shared(
                    pname,
                    value,
                    decay(lr.mlp_init, lr.mlp_final),
                    lr.weight_decay,
                ));
            }
        }
        out
    }

    /// Names of every parameter, in binding order (the names of
    /// [`Representation::params_mut`]).
    pub fn param_names(&self) -> Vec<String> {
        let mut out: Vec<String> = ["xyz", "log_scale", "rotation", "opacity", "sh_dc"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        if self.has_sh_rest() {
            out.push("sh_rest".into());
        }
        out.push("t_centre".into());
        out.extend(PLANE_NAMES.iter().map(|p| format!("field.{p}")));
        for (name, mlp) in self.named_mlps() {
            for i in 0..mlp.layers.len() {
                out.push(format!("{name}.{i}.weight"));
                out.push(format!("{name}.{i}.bias"));
            }
        }
        out
    }

    fn named_mlps(&self) -> Vec<(&'static str, &Mlp<T>)> {
        let mut v = vec![("motion_mlp", &self.motion_mlp), ("rot_mlp", &self.rot_mlp)];
        if let Some(m) = &self.sh_mlp {
            v.push(("sh_mlp", m));
        }
        v.push(("life_mlp", &self.life_mlp));
        v
    }

    /// Copies of every parameter, in binding order (inputs of a gradient check).
    pub fn param_tensors(&self) -> Vec<Tensor<T>> {
        self.param_refs().into_iter().cloned().collect()
    }

    fn vars_from_list<'t>(&self, vars: &[Var<'t, T>]) -> ParamVars<'t, T> {
        let mut it = vars.iter().copied();
        let mut next = || it.next().expect("SaroModel: too few parameter vars");
        let xyz = next();
        let log_scale = next();
        let rotation = next();
        let opacity = next();
        let sh_dc = next();
        let sh_rest = self.has_sh_rest().then(&mut next);
        let t_centre = next();
        let planes = (0..6).map(|_| next()).collect();
        let mut rest = vars
            .iter()
            .copied()
            .skip(if self.has_sh_rest() { 13 } else { 12 });
        let motion = mlp_vars(&mut rest, &self.motion_mlp);
        let rot = mlp_vars(&mut rest, &self.rot_mlp);
        let sh = self.sh_mlp.as_ref().map(|m| mlp_vars(&mut rest, m));
        let life = mlp_vars(&mut rest, &self.life_mlp);
        assert!(rest.next().is_none(), "SaroModel: too many parameter vars");
        ParamVars {
            xyz,
            log_scale,
            rotation,
            opacity,
            sh_dc,
            sh_rest,
            t_centre,
            planes,
            motion,
            rot,
            sh,
            life,
        }
    }

    /// The stop-gradient inputs read from the current parameters.
    pub fn detached(&self) -> Detached {
        let scales = self.log_scale.map(|v| v.exp());
        let query = self
            .field
            .query(self.xyz.data(), self.t_centre.data(), scales.data());
        Detached {
            query: Arc::new(query),
            t_centre: Arc::new(
                self.t_centre
                    .data()
                    .iter()
                    .map(|&v| Float::to_f64(v))
                    .collect(),
            ),
        }
    }

    /// Binds the model given parameter handles in binding order (as registered by
    /// [`Representation::bind`], or anonymous vars in a gradient check) and the
    /// stop-gradient inputs.
    pub fn bind_vars<'t>(&self, vars: &[Var<'t, T>], detached: &Detached) -> SaroBound<'t, T> {
        let p = self.vars_from_list(vars);
        let tape = p.xyz.tape();
        let n = self.xyz.rows();
        let k = self.config.sh_coeffs();
        let sh = match p.sh_rest {
            Some(rest) => concat(&[p.sh_dc, rest], 1),
            None => p.sh_dc,
        };
        let opacity = p.opacity.sigmoid();
        let dynamic = self.dynamic.then(|| {
            let sample = PlaneSample::new(&self.field, detached.query.clone());
            #[cfg(test)]
            let sample = if self.corrupt_field_backward {
                sample.corrupted()
            } else {
                sample
            };
            let features = tape.apply1(sample, &p.planes);
            // l = (1 - m)(1 - sigmoid(z)) + m = 1 - (1 - m) sigmoid(z).
            let m = self.config.min_lifespan();
            let lifespan = p
                .life
                .forward(features)
                .sigmoid()
                .scale(-(1.0 - m))
                .add_scalar(1.0)
                .reshape(&[n]);
            // L_SR: the scale residual at Dt = 0, i.e. PE(0).
            let pe0 = time_embedding::<T>(std::iter::repeat_n(0.0, n), self.config.time_freqs);
            let h0 = concat(&[features, tape.constant(pe0)], 1);
            let l_sr = tape.apply1(Norm2, &[p.rot.forward(h0).slice(1, 4, 7)]);
            DynamicVars {
                t_centre: p.t_centre,
                features,
                lifespan,
                t_centre_detached: detached.t_centre.clone(),
                motion: p.motion,
                rot: p.rot,
                sh: p.sh,
                l_sr,
                lambda_sr: self.config.lambda_sr,
            }
        });
        SaroBound {
            n,
            k,
            time_freqs: self.config.time_freqs,
            xyz: p.xyz,
            log_scale: p.log_scale,
            rotation: p.rotation,
            opacity,
            sh,
            dynamic,
        }
    }

    /// Binds on `tape` with every parameter registered by name; the concrete type of
    /// [`Representation::bind`] (gives access to lifespans, features and L_SR).
    pub fn bind_saro<'t>(&self, tape: &'t Tape<T>) -> SaroBound<'t, T> {
        let names = self.param_names();
        let vars: Vec<Var<'t, T>> = names
            .iter()
            .zip(self.param_refs())
            .map(|(name, t)| tape.param(name, t.clone()))
            .collect();
        self.bind_vars(&vars, &self.detached())
    }

    /// Immutable references to every parameter, in binding order.
    fn param_refs(&self) -> Vec<&Tensor<T>> {
        let mut out = vec![
            &self.xyz,
            &self.log_scale,
            &self.rotation,
            &self.opacity,
            &self.sh_dc,
        ];
        if self.has_sh_rest() {
            out.push(&self.sh_rest);
        }
        out.push(&self.t_centre);
        out.extend(self.field.planes.iter());
        for (_, m) in self.named_mlps() {
            for l in &m.layers {
                out.push(&l.weight);
                out.push(&l.bias);
            }
        }
        out
    }

    /// Lifespans `l` \[N] from the current parameters (no gradient).
    pub fn lifespans(&self) -> Vec<f64> {
        let tape = Tape::<T>::new();
        let planes: Vec<_> = self
            .field
            .planes
            .iter()
            .map(|p| tape.constant(p.clone()))
            .collect();
        let features = tape.apply1(
            PlaneSample::new(&self.field, self.detached().query),
            &planes,
        );
        let m = self.config.min_lifespan();
        let z = self.life_mlp.bind(&tape, "life_mlp").forward(features);
        let s = z.sigmoid();
        let v = s.value();
        v.data()
            .iter()
            .map(|&s| 1.0 - (1.0 - m) * Float::to_f64(s))
            .collect()
    }

    /// Temporal integral of each Gaussian's opacity factor over t in \[0, 1] (SaRO-GS
    /// `get_intergral`, the code's "Eq 22"):
    /// `I = l sqrt(pi)/2 \[Q(2 sqrt2 (1 - mu_t)/l) - Q(2 sqrt2 (0 - mu_t)/l)]`, with the
    /// logistic approximation of the normal CDF
    /// `Q(x) = 1 - 1/(1 + exp(0.070565902 x^3 + 1.5976 x))`.
    pub fn temporal_integral(&self) -> Vec<f64> {
        let q = |x: f64| 1.0 - 1.0 / (1.0 + (0.070_565_902 * x * x * x + 1.5976 * x).exp());
        let r = 2.0 * std::f64::consts::SQRT_2;
        self.lifespans()
            .iter()
            .zip(self.t_centre.data())
            .map(|(&l, &mu)| {
                let mu = Float::to_f64(mu);
                l * std::f64::consts::PI.sqrt() / 2.0
                    * (q(r * (1.0 - mu) / l) - q(r * (0.0 - mu) / l))
            })
            .collect()
    }

    fn per_gaussian_mut(&mut self) -> [&mut Tensor<T>; 7] {
        [
            &mut self.xyz,
            &mut self.log_scale,
            &mut self.rotation,
            &mut self.opacity,
            &mut self.sh_dc,
            &mut self.sh_rest,
            &mut self.t_centre,
        ]
    }
}

impl<T: Float> Representation<T> for SaroModel<T> {
    fn name(&self) -> &'static str {
        "saro"
    }

    fn num_gaussians(&self) -> usize {
        self.xyz.rows()
    }

    /// Static stage for iterations `<= static_iterations`, dynamic after (SaRO-GS
    /// `train.py`: `if iteration > opt.static_iteration: stage = "dynamatic"`).
    fn set_iteration(&mut self, iteration: usize) {
        self.dynamic = iteration > self.config.static_iterations;
    }

    fn bind<'t>(&self, tape: &'t Tape<T>) -> Box<dyn Bound<'t, T> + 't> {
        Box::new(self.bind_saro(tape))
    }

    fn params_mut(&mut self) -> Vec<ParamSlot<'_, T>> {
        self.slots()
    }

    fn select_rows(&mut self, index: &[usize]) {
        for t in self.per_gaussian_mut() {
            t.select_rows(index);
        }
    }

    fn set_rows(&mut self, rows: &[usize], means: &Tensor<T>, scales: &Tensor<T>) {
        assert_eq!(means.shape(), &[rows.len(), 3], "set_rows: means shape");
        assert_eq!(scales.shape(), &[rows.len(), 3], "set_rows: scales shape");
        for (j, &r) in rows.iter().enumerate() {
            for a in 0..3 {
                self.xyz.data_mut()[3 * r + a] = means.data()[3 * j + a];
                self.log_scale.data_mut()[3 * r + a] = scales.data()[3 * j + a].ln();
            }
        }
    }

    fn canonical(&self) -> Canonical<T> {
        Canonical {
            means: self.xyz.clone(),
            scales: self.log_scale.map(|v| v.exp()),
            quats: self.rotation.clone(),
            opacity: self.opacity.map(sigmoid),
        }
    }

    /// `o = min(o, logit(max_opacity))` (3DGS `reset_opacity`).
    fn reset_opacity(&mut self, max_opacity: f64) -> Vec<String> {
        let cap = T::of(logit(max_opacity));
        for v in self.opacity.data_mut() {
            *v = v.min(cap);
        }
        vec!["opacity".to_string()]
    }

    /// Gaussians whose temporal integral is below `min_integral` (SaRO-GS prunes them
    /// every 50 iterations of the dynamic stage and at each densification). Empty in
    /// the static stage, where the temporal factor is not used.
    fn short_lived(&self) -> Vec<usize> {
        if !self.dynamic {
            return Vec::new();
        }
        let min = self.config.min_integral;
        self.temporal_integral()
            .iter()
            .enumerate()
            .filter(|&(_, &i)| i.is_nan() || i < min)
            .map(|(k, _)| k)
            .collect()
    }

    fn num_scalars(&self) -> usize {
        self.param_refs().iter().map(|t| t.len()).sum()
    }

    /// `x + MLP_x(\[f, PE(t - mu_t)])` per time, with the field queried once and only
    /// the motion MLP evaluated (one small scratch tape per time, so memory stays
    /// O(N H)). In the static stage the centres do not move.
    fn centres_at_times(&self, times: &[f64]) -> Vec<Tensor<T>> {
        if !self.dynamic {
            return times.iter().map(|_| self.xyz.clone()).collect();
        }
        let features = {
            let tape = Tape::<T>::new();
            let planes: Vec<_> = self
                .field
                .planes
                .iter()
                .map(|p| tape.constant(p.clone()))
                .collect();
            let detached = self.detached();
            let f = tape.apply1(PlaneSample::new(&self.field, detached.query), &planes);
            f.value().clone()
        };
        times
            .iter()
            .map(|&time| {
                let tape = Tape::<T>::new();
                let pe = time_embedding::<T>(
                    self.t_centre
                        .data()
                        .iter()
                        .map(|&m| time - Float::to_f64(m)),
                    self.config.time_freqs,
                );
                let mut h = concat(&[tape.constant(features.clone()), tape.constant(pe)], 1);
                let last = self.motion_mlp.layers.len() - 1;
                for (i, l) in self.motion_mlp.layers.iter().enumerate() {
                    h = h.matmul(tape.constant(l.weight.clone())) + tape.constant(l.bias.clone());
                    if i < last {
                        h = h.relu();
                    }
                }
                // The binding ends the borrow of the tape before the tape is dropped.
                #[allow(clippy::let_and_return)]
                let centres = (tape.constant(self.xyz.clone()) + h).value().clone();
                centres
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use maaf_autodiff::check::{GradcheckConfig, gradcheck, tests_support::random_tensor};
    use maaf_autodiff::nn::Linear;

    fn tiny_config() -> SaroConfig {
        SaroConfig {
            field: KPlaneConfig {
                spatial_res: 4,
                time_res: 3,
                channels: 3,
                max_mip_level: 7,
            },
            hidden: 5,
            time_freqs: 2,
            sh_degree: 1,
            duration: 10.0,
            ..SaroConfig::default()
        }
    }

    fn tiny_model<T: Float>(n: usize, seed: u64) -> SaroModel<T> {
        let cloud = PointCloud::random_in_box(n, -1.0, 1.0, seed);
        let mut m = SaroModel::<T>::from_point_cloud(&cloud, tiny_config(), 2.0, seed);
        m.set_iteration(m.config.static_iterations + 1);
        m
    }

    #[test]
    fn zero_heads_give_the_canonical_scene_times_the_temporal_factor() {
        let mut model = tiny_model::<f32>(40, 1);
        // Random planes so that the field, the lifespans and the MLP hidden layers are
        // all non-trivial; only the zero output layers keep the residuals at zero.
        for (p, plane) in model.field.planes.iter_mut().enumerate() {
            *plane = random_tensor(plane.shape(), -1.0, 1.0, 7 + p as u64);
        }
        let canon = model.canonical();
        let lifespans = model.lifespans();
        let tape = Tape::new();
        let bound = model.bind_saro(&tape);
        assert!(bound.l_sr().expect("dynamic").value().item() == 0.0);
        for time in [0.0, 0.37, 1.0] {
            let g = bound.deform(time);
            // Exactly: x + 0 = x, exp(s + 0) = exp(s), q + 0 = q, SH + 0 = SH.
            assert_eq!(*g.means.value(), canon.means);
            assert_eq!(*g.scales.value(), canon.scales);
            assert_eq!(*g.quats.value(), canon.quats);
            let sh = g.sh.value();
            assert_eq!(sh.shape(), &[40, 4, 3]);
            for i in 0..40 {
                assert_eq!(
                    &sh.data()[i * 12..i * 12 + 3],
                    &model.sh_dc.data()[i * 3..i * 3 + 3]
                );
                assert!(
                    sh.data()[i * 12 + 3..(i + 1) * 12]
                        .iter()
                        .all(|&v| v == 0.0)
                );
            }
            let opacity = g.opacity.value();
            for (i, &l) in lifespans.iter().enumerate() {
                let dt = time - f64::from(model.t_centre.data()[i]);
                let w = (-4.0 * (dt / l).powi(2)).exp();
                let want = f64::from(canon.opacity.data()[i]) * w;
                // f32 products of an exp and a sigmoid: a few ulps of values <= 1.
                assert!(
                    (f64::from(opacity.data()[i]) - want).abs() <= 1e-6,
                    "{i}: {} vs {want}",
                    opacity.data()[i]
                );
            }
            let l = &lifespans;
            let m = model.config.min_lifespan();
            assert!(l.iter().all(|&l| l >= m && l <= 1.0));
        }
        // The static stage is plain 3DGS: no temporal factor, no regulariser.
        model.set_iteration(1);
        let tape = Tape::new();
        let bound = model.bind(&tape);
        let g = bound.deform(0.5);
        assert_eq!(*g.opacity.value(), canon.opacity);
        assert!(bound.regularisers().is_empty());
    }

    /// A tiny f64 model where nothing is trivially zero: random planes, random residual
    /// heads, random SH bands.
    fn busy_model(n: usize) -> SaroModel<f64> {
        let mut m = tiny_model::<f64>(n, 5);
        for (p, plane) in m.field.planes.iter_mut().enumerate() {
            *plane = random_tensor(plane.shape(), -1.0, 1.0, 20 + p as u64);
        }
        let heads = [&mut m.motion_mlp, &mut m.rot_mlp];
        for (k, mlp) in heads.into_iter().enumerate() {
            let last = mlp.layers.last_mut().expect("layers");
            let (i, o) = (last.weight.shape()[0], last.weight.shape()[1]);
            *last = Linear::new(i, o, 40 + k as u64);
        }
        if let Some(mlp) = m.sh_mlp.as_mut() {
            let last = mlp.layers.last_mut().expect("layers");
            let (i, o) = (last.weight.shape()[0], last.weight.shape()[1]);
            *last = Linear::new(i, o, 42);
        }
        m.sh_rest = random_tensor(m.sh_rest.shape(), -0.3, 0.3, 43);
        m.log_scale = random_tensor(m.log_scale.shape(), -4.0, 0.0, 44);
        m
    }

    /// Every deformed output at two times plus L_SR, flattened into one vector: the
    /// gradcheck contracts it with a random cotangent, i.e. checks a random scalar
    /// function of all of them.
    fn all_outputs<'t>(m: &SaroModel<f64>, v: &[Var<'t, f64>], d: &Detached) -> Var<'t, f64> {
        let bound = m.bind_vars(v, d);
        let mut parts = Vec::new();
        for time in [0.2, 0.75] {
            let g = bound.deform(time);
            for x in [g.means, g.scales, g.quats, g.opacity, g.sh] {
                let len = x.value().len();
                parts.push(x.reshape(&[len]));
            }
        }
        for r in bound.regularisers() {
            parts.push(r.value.reshape(&[1]));
        }
        concat(&parts, 0)
    }

    #[test]
    fn gradcheck_field_mlp_temporal_opacity_to_deformed_gaussians() {
        let model = busy_model(6);
        let inputs = model.param_tensors();
        // Stop-gradient inputs are held at the unperturbed values: the finite
        // differences then see exactly the function whose gradient the tape computes.
        let detached = model.detached();
        // Smooth O(1) compositions of exp/sigmoid/matmul/bilinear taps: central
        // differences with eps 1e-6 are accurate to ~1e-9; atol 1e-6 / rtol 1e-5
        // still catch a wrong factor or a dropped tap by orders of magnitude.
        let cfg = GradcheckConfig::default().with_tol(1e-6, 1e-5);
        let report = gradcheck(|_, v| all_outputs(&model, v, &detached), &inputs, &cfg);
        report.assert_passed();
        assert!(report.checked > 500, "only {} coordinates", report.checked);

        let mut bad = model.clone();
        bad.corrupt_field_backward = true;
        let report = gradcheck(|_, v| all_outputs(&bad, v, &detached), &inputs, &cfg);
        assert!(
            !report.passed(),
            "negative control: a wrong field backward passed"
        );
        let names = model.param_names();
        assert!(
            report
                .failures()
                .iter()
                .all(|f| names[f.input].starts_with("field.")),
            "only the planes' gradients should be wrong"
        );
    }

    #[test]
    fn norm2_gradcheck_and_zero_subgradient() {
        let x = random_tensor(&[4, 3], -1.0, 1.0, 9);
        gradcheck(|t, v| t.apply1(Norm2, v), &[x], &GradcheckConfig::default()).assert_passed();
        let tape = Tape::<f64>::new();
        let z = tape.var(Tensor::zeros(&[5, 3]));
        let n = tape.apply1(Norm2, &[z]);
        let grads = tape.backward(n).expect("finite");
        assert!(grads.wrt(z).expect("grad").data().iter().all(|&g| g == 0.0));
    }

    #[test]
    fn select_rows_resizes_every_per_gaussian_container_in_lock_step() {
        let mut model = busy_model(5);
        let before = model.clone();
        // Prune 1 and 3, clone 2, split 4 into two rows.
        let index = [0, 2, 2, 4, 4];
        model.select_rows(&index);
        assert_eq!(model.num_gaussians(), 5);
        let shared_before: Vec<Tensor<f64>> = before
            .clone()
            .params_mut()
            .into_iter()
            .filter(|s| !s.per_gaussian)
            .map(|s| s.value.clone())
            .collect();
        let mut before_mut = before.clone();
        let old: Vec<(String, Tensor<f64>)> = before_mut
            .params_mut()
            .into_iter()
            .map(|s| (s.name, s.value.clone()))
            .collect();
        let mut shared_after = Vec::new();
        for slot in model.params_mut() {
            if !slot.per_gaussian {
                shared_after.push(slot.value.clone());
                continue;
            }
            assert_eq!(slot.value.rows(), index.len(), "{}", slot.name);
            let (_, o) = old
                .iter()
                .find(|(n, _)| *n == slot.name)
                .expect("same names");
            let w = o.row_len();
            for (new_row, &old_row) in index.iter().enumerate() {
                assert_eq!(
                    &slot.value.data()[new_row * w..(new_row + 1) * w],
                    &o.data()[old_row * w..(old_row + 1) * w],
                    "{} row {new_row}",
                    slot.name
                );
            }
        }
        assert_eq!(
            shared_after, shared_before,
            "shared parameters must not change"
        );
        // A split then moves the two halves: only those rows change.
        let means = Tensor::from_vec(vec![0.1, 0.2, 0.3, -0.1, -0.2, -0.3], &[2, 3]);
        let scales = Tensor::from_vec(vec![0.01, 0.02, 0.03, 0.04, 0.05, 0.06], &[2, 3]);
        let kept = model.clone();
        model.set_rows(&[3, 4], &means, &scales);
        let c = model.canonical();
        assert_eq!(&c.means.data()[9..15], means.data());
        for (a, b) in c.scales.data()[9..15].iter().zip(scales.data()) {
            assert!((a - b).abs() <= 1e-15 * b, "exp(ln s) round trip");
        }
        assert_eq!(&c.means.data()[..9], &kept.xyz.data()[..9]);
        assert_eq!(model.rotation, kept.rotation);
        // The resized model still binds and deforms with consistent shapes.
        let tape = Tape::new();
        let g = model.bind(&tape).deform(0.5);
        assert_eq!(g.means.shape().as_slice(), &[5, 3]);
        assert_eq!(g.opacity.shape().as_slice(), &[5]);
        assert_eq!(g.sh.shape().as_slice(), &[5, 4, 3]);
    }

    #[test]
    fn temporal_integral_matches_quadrature_and_flags_short_lived() {
        let mut model = tiny_model::<f64>(8, 3);
        let integral = model.temporal_integral();
        let lifespans = model.lifespans();
        for i in 0..8 {
            let (mu, l) = (model.t_centre.data()[i], lifespans[i]);
            // Midpoint rule with 20 000 cells: error ~1e-9 for these smooth integrands;
            // the logistic CDF approximation itself is good to ~1e-4 (SaRO-GS Eq 22).
            let steps = 20_000;
            let quad: f64 = (0..steps)
                .map(|k| {
                    let t = (k as f64 + 0.5) / steps as f64;
                    (-4.0 * ((t - mu) / l).powi(2)).exp() / steps as f64
                })
                .sum();
            assert!(
                (integral[i] - quad).abs() < 1e-3 * l,
                "{i}: {} vs {quad}",
                integral[i]
            );
        }
        // Move Gaussian 2 far outside [0, 1] in time: its integral vanishes.
        model.t_centre.data_mut()[2] = 5.0;
        assert_eq!(model.short_lived(), vec![2]);
        model.set_iteration(1);
        assert!(
            model.short_lived().is_empty(),
            "no temporal pruning in the static stage"
        );
    }

    #[test]
    fn param_slots_are_named_as_bound_and_scaled_by_extent() {
        let mut model = tiny_model::<f32>(4, 1);
        let names = model.param_names();
        let tape = Tape::new();
        let bound = model.bind(&tape);
        let loss = {
            let g = bound.deform(0.5);
            let mut l =
                g.means.sum() + g.scales.sum() + g.quats.sum() + g.opacity.sum() + g.sh.sum();
            for r in bound.regularisers() {
                l = l + r.value;
            }
            l
        };
        let grads = tape.backward(loss).expect("finite");
        let mut tape_names = grads.param_names();
        tape_names.sort_unstable();
        let mut sorted = names.clone();
        sorted.sort_unstable();
        assert_eq!(
            tape_names,
            sorted.iter().map(String::as_str).collect::<Vec<_>>()
        );
        let slots = model.params_mut();
        assert_eq!(
            slots.iter().map(|s| s.name.clone()).collect::<Vec<_>>(),
            names
        );
        let xyz = &slots[0];
        assert_eq!(xyz.name, "xyz");
        // Extent 2.0 in tiny_model: 1.6e-4 * 2.
        assert!((xyz.lr.at(0) - 3.2e-4).abs() < 1e-12);
        assert_eq!(slots.iter().filter(|s| s.per_gaussian).count(), 7);
    }

    /// CPU time of this thread in seconds (Linux `/proc/thread-self/schedstat`, first
    /// field in ns), so the cost report is meaningful on a shared, loaded machine.
    fn thread_cpu_seconds() -> f64 {
        std::fs::read_to_string("/proc/thread-self/schedstat")
            .ok()
            .and_then(|s| s.split_whitespace().next().map(str::to_string))
            .and_then(|s| s.parse::<f64>().ok())
            .map_or(f64::NAN, |ns| ns * 1e-9)
    }

    /// Cost of the default configuration at N = 20 000 (one view per step):
    /// `cargo test -p maaf-train --release cost_report -- --ignored --nocapture`.
    /// Prints thread CPU times (single-threaded code); never asserts a time (DESIGN.md
    /// section 9).
    #[test]
    #[ignore]
    fn cost_report() {
        let clock = thread_cpu_seconds;
        let n = 20_000;
        let cloud = PointCloud::random_in_box(n, -1.3, 1.3, 1);
        for (label, config) in [
            ("default", SaroConfig::default()),
            (
                "no SH residual",
                SaroConfig {
                    sh_residual: false,
                    ..SaroConfig::default()
                },
            ),
            (
                "reference widths (H 128, t 128)",
                SaroConfig {
                    hidden: 128,
                    field: KPlaneConfig {
                        time_res: 128,
                        ..KPlaneConfig::default()
                    },
                    ..SaroConfig::default()
                },
            ),
        ] {
            let mut model = SaroModel::<f32>::from_point_cloud(&cloud, config, 1.0, 1);
            // Non-zero planes so the timing includes every path.
            for (p, plane) in model.field.planes.iter_mut().enumerate() {
                *plane = random_tensor(plane.shape(), -0.1, 0.1, p as u64);
            }
            model.set_dynamic(true);
            let field = model.field.num_scalars();
            let mlps: usize = model.named_mlps().iter().map(|(_, m)| m.num_params()).sum();
            let per_gaussian = (model.num_scalars() - field - mlps) / n;
            println!(
                "{label}: planes {field} scalars ({:.2} MB f32), MLPs {mlps} ({:.2} MB), \
                 {per_gaussian} scalars per Gaussian ({:.2} MB at N = {n}); Adam triples all",
                field as f64 * 4e-6,
                mlps as f64 * 4e-6,
                (per_gaussian * n) as f64 * 4e-6
            );
            let reps = 3;
            let mut t = [0.0; 5];
            for _ in 0..reps {
                let tape = Tape::new();
                let t0 = clock();
                let planes: Vec<_> = model
                    .field
                    .planes
                    .iter()
                    .map(|p| tape.var(p.clone()))
                    .collect();
                let f = tape.apply1(
                    PlaneSample::new(&model.field, model.detached().query),
                    &planes,
                );
                let t1 = clock();
                tape.backward(f.sum()).expect("finite");
                let t2 = clock();
                let tape = Tape::new();
                let t3 = clock();
                let bound = model.bind_saro(&tape);
                let t4 = clock();
                let g = bound.deform(0.4);
                let mut loss = g.means.sum() + g.scales.sum() + g.quats.sum();
                loss = loss + g.opacity.sum() + g.sh.sum();
                loss = loss + bound.l_sr().expect("dynamic");
                let t5 = clock();
                tape.backward(loss).expect("finite");
                let t6 = clock();
                for (acc, d) in t
                    .iter_mut()
                    .zip([t1 - t0, t2 - t1, t4 - t3, t5 - t4, t6 - t5])
                {
                    *acc += d / reps as f64 * 1e3;
                }
            }
            let times: Vec<f64> = (0..5).map(|k| k as f64 / 4.0).collect();
            let c0 = clock();
            let centres = model.centres_at_times(&times);
            let per_time = (clock() - c0) / times.len() as f64 * 1e3;
            assert_eq!(centres.len(), times.len());
            println!("  centres_at_times: {per_time:.0} ms CPU per time");
            println!(
                "  CPU ms per step: field lookup fwd {:.0} / bwd {:.0} (included below); \
                 bind {:.0}, deform(t) {:.0}, backward {:.0}, total {:.0}",
                t[0],
                t[1],
                t[2],
                t[3],
                t[4],
                t[2] + t[3] + t[4]
            );
        }
    }

    /// Where the MLP time goes: one \[20000,41]x\[41,64] GEMM vs the row-broadcast
    /// bias add and the ReLU on its output (forward + backward each).
    #[test]
    #[ignore]
    fn cost_breakdown_dense_layer() {
        let clock = thread_cpu_seconds;
        let x = random_tensor::<f32>(&[20_000, 41], -1.0, 1.0, 1);
        let w = random_tensor::<f32>(&[41, 64], -1.0, 1.0, 2);
        let b = random_tensor::<f32>(&[64], -1.0, 1.0, 3);
        let tape = Tape::new();
        let (x, w, b) = (tape.var(x), tape.var(w), tape.var(b));
        let t0 = clock();
        let y = x.matmul(w);
        let t1 = clock();
        let z = y + b;
        let t2 = clock();
        let r = z.relu();
        let t3 = clock();
        let s = r.sum();
        let t4 = clock();
        tape.backward(s).expect("finite");
        let t5 = clock();
        println!(
            "matmul {:.1} ms, bias add {:.1} ms, relu {:.1} ms, sum {:.1} ms, backward of all {:.1} ms",
            (t1 - t0) * 1e3,
            (t2 - t1) * 1e3,
            (t3 - t2) * 1e3,
            (t4 - t3) * 1e3,
            (t5 - t4) * 1e3
        );
    }

    #[test]
    fn centres_at_times_equal_the_deformed_means() {
        let mut model = busy_model(7);
        let times = [0.0, 0.3, 0.9];
        let fast = model.centres_at_times(&times);
        for (&t, c) in times.iter().zip(&fast) {
            let tape = Tape::new();
            let want = model.bind(&tape).deform(t).means.value().clone();
            // Same operations in the same order: bit-identical.
            assert_eq!(*c, want);
        }
        model.set_iteration(1);
        assert_eq!(model.centres_at_times(&[0.5])[0], model.xyz);
    }

    #[test]
    fn the_trainer_can_hold_any_representation_as_a_trait_object() {
        let model: Box<dyn Representation<f32>> = Box::new(tiny_model::<f32>(3, 2));
        assert_eq!(model.name(), "saro");
        assert_eq!(model.num_gaussians(), 3);
        let tape = Tape::new();
        let bound = model.bind(&tape);
        assert_eq!(bound.deform(0.1).quats.shape().as_slice(), &[3, 4]);
        assert_eq!(bound.regularisers()[0].name, "l_sr");
    }
}
