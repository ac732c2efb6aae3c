//! Configuration of the Deformable-3DGS representation: network shape, warm-up and
//! learning rates (ingra14m/Deformable-3D-Gaussians `arguments/__init__.py`,
//! `utils/time_utils.py`, `scene/deform_model.py`).

use serde::{Deserialize, Serialize};

/// Learning rates of Deformable-3DGS (`OptimizationParams`, `GaussianModel.training_setup`,
/// `DeformModel.train_setting`). Centres decay from `position_init * s` to
/// `position_final * s` over `position_max_steps` (s = `spatial_lr_scale`); the network
/// from `deform_init` to `deform_final` over `deform_max_steps`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeformLr {
    /// Centres at iteration 0, times `spatial_lr_scale` (1.6e-4).
    pub position_init: f64,
    /// Centres at the end of the decay, times `spatial_lr_scale` (1.6e-6).
    pub position_final: f64,
    /// Length of the centres' decay (30 000).
    pub position_max_steps: usize,
    /// Deformation network at iteration 0 (`position_lr_init * spatial_lr_scale` = 8e-4).
    pub deform_init: f64,
    /// Deformation network at the end of its decay (`position_lr_final` = 1.6e-6, not
    /// scaled).
    pub deform_final: f64,
    /// Length of the network's decay (`deform_lr_max_steps` = 40 000).
    pub deform_max_steps: usize,
    /// SH DC (2.5e-3); the higher bands use `feature / 20`.
    pub feature: f64,
    /// Opacity logit (0.05).
    pub opacity: f64,
    /// Log-scale (1e-3).
    pub scaling: f64,
    /// Quaternion (1e-3).
    pub rotation: f64,
}

impl Default for DeformLr {
    fn default() -> Self {
        DeformLr {
            position_init: 1.6e-4,
            position_final: 1.6e-6,
            position_max_steps: 30_000,
            deform_init: 8e-4,
            deform_final: 1.6e-6,
            deform_max_steps: 40_000,
            feature: 2.5e-3,
            opacity: 0.05,
            scaling: 1e-3,
            rotation: 1e-3,
        }
    }
}

/// Configuration of the Deformable-3DGS representation (`--model deform`; missing
/// fields take the defaults).
///
/// The reference network (`DeformNetwork(is_blender=True)`) is `depth` 8 layers of
/// `width` 256 with ReLU, the encoded input concatenated again after layer
/// `depth / 2`, a time network `PE(t) -> 256 -> 30`, 10 frequencies for the centre
/// and 6 for the time. The CPU defaults are smaller (see `DeformConfig::default`
/// and README's measurement); [`DeformConfig::reference`] is the paper-size network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeformConfig {
    /// Hidden layers of the deformation MLP (reference 8).
    pub depth: usize,
    /// Width of every hidden layer (reference 256).
    pub width: usize,
    /// Concatenate the encoded input to the hidden state after layer `depth / 2`
    /// (reference: `skips = [D // 2]`).
    pub skip: bool,
    /// Frequencies of the centre's encoding (`multires` 10: 63 inputs).
    pub x_freqs: usize,
    /// Frequencies of the time's encoding (6 for D-NeRF, `is_blender`: 13 inputs).
    pub t_freqs: usize,
    /// Hidden width of the time network `PE(t) -> width -> time_out` (256 in the
    /// reference's D-NeRF setting); 0 feeds `PE(t)` to the MLP directly (the
    /// reference's setting for real scenes).
    pub time_width: usize,
    /// Outputs of the time network (30).
    pub time_out: usize,
    /// SH degree (0..=3).
    pub sh_degree: usize,
    /// Iterations rendered as plain 3D Gaussians before the network is used
    /// (`warm_up` 3000: `iteration < warm_up` is static).
    pub warm_up: usize,
    /// Multiplier of the centres' learning rate (Deformable-3DGS sets
    /// `spatial_lr_scale = 5` for every scene instead of the camera extent).
    pub spatial_lr_scale: f64,
    /// Learning rates.
    pub lr: DeformLr,
    /// SpeeDe3DGS's GroupFlow (off by default: `groups` = 0).
    pub group_flow: GroupFlowConfig,
}

/// GroupFlow (SpeeDe3DGS `OptimizationParams`: `gflow_num` 500 groups from
/// `gflow_iteration` 15 000, at most `gflow_tnum_max` 200 time knots, node learning
/// rate `gflow_xyz_lr` 1e-5). From iteration `at` on, Gaussians move with their
/// group's rigid motion instead of the MLP (module `group_flow`).
///
/// The reference also trains the knots' rotations and translations, at a learning
/// rate of 1e-7: an Adam step moves a value by about its learning rate, so over the
/// 15 000 iterations left there they move by at most 1.5e-3. Here they stay as fitted
/// and only the nodes train.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroupFlowConfig {
    /// Number of groups (0 = off; the reference's 500 when on).
    pub groups: usize,
    /// Iteration at which the groups are fitted (the reference's 15 000, where
    /// densification ends).
    pub at: usize,
    /// Most time knots (one per training frame up to this many).
    pub max_knots: usize,
    /// Learning rate of the group nodes.
    pub node_lr: f64,
    /// Turn each Gaussian's quaternion with its group (the reference's
    /// `gflow_local_rot`, off there by default; on here).
    pub rotate_gaussians: bool,
}

impl Default for GroupFlowConfig {
    fn default() -> Self {
        GroupFlowConfig {
            groups: 0,
            at: 15_000,
            max_knots: 200,
            node_lr: 1e-5,
            rotate_gaussians: true,
        }
    }
}

impl Default for DeformConfig {
    /// The CPU default: 4 layers of 128 with the skip and the reference's encodings
    /// and time network. Measured on mutant (README, "A second representation"): one
    /// step at 10k Gaussians takes 50 / 71 / 234 ms with 4 x 64 / 4 x 128 / 8 x 256,
    /// and 3000 iterations reach 28.07 / 28.36 / 28.73 dB at 1x; 4 x 128 buys most of
    /// the reference's quality at 30% of its step time.
    fn default() -> Self {
        DeformConfig {
            depth: 4,
            width: 128,
            ..Self::reference()
        }
    }
}

impl DeformConfig {
    /// The reference's network and schedule: 8 layers of 256, skip after layer 4.
    pub fn reference() -> Self {
        DeformConfig {
            depth: 8,
            width: 256,
            skip: true,
            x_freqs: 10,
            t_freqs: 6,
            time_width: 256,
            time_out: 30,
            sh_degree: 3,
            warm_up: 3000,
            spatial_lr_scale: 5.0,
            lr: DeformLr::default(),
            group_flow: GroupFlowConfig::default(),
        }
    }

    /// SH coefficients per colour channel, `(degree + 1)^2`.
    pub fn sh_coeffs(&self) -> usize {
        (self.sh_degree + 1) * (self.sh_degree + 1)
    }

    /// Width of the encoded centre, `3 (1 + 2 x_freqs)`.
    pub fn x_dim(&self) -> usize {
        3 * (1 + 2 * self.x_freqs)
    }

    /// Width of the time features the MLP sees: `time_out`, or `1 + 2 t_freqs`
    /// without the time network.
    pub fn t_dim(&self) -> usize {
        if self.time_width > 0 {
            self.time_out
        } else {
            1 + 2 * self.t_freqs
        }
    }

    /// Layer widths of the deformation MLP, input first: with `skip`, the trunk up
    /// to and including layer `depth / 2` and then the layers after the skip with the
    /// 10-output head (`[dx, dq, ds]`), whose input is the encoded input plus the
    /// trunk's output; without, one network. The time network is not included.
    pub fn network_widths(&self) -> (Vec<usize>, Option<Vec<usize>>) {
        let input = self.x_dim() + self.t_dim();
        let layers = |first: usize, hidden: usize, head: bool| -> Vec<usize> {
            let mut w = vec![first];
            w.extend(std::iter::repeat_n(self.width, hidden));
            w.extend(head.then_some(10));
            w
        };
        if self.skip {
            let before = self.depth / 2 + 1;
            (
                layers(input, before, false),
                Some(layers(input + self.width, self.depth - before, true)),
            )
        } else {
            (layers(input, self.depth, true), None)
        }
    }

    /// Checks every size and rate, naming the field and its allowed range.
    pub fn validate(&self) -> Result<(), String> {
        let bad = |field: &str, range: &str, v: &dyn std::fmt::Display| {
            Err(format!("model.{field} = {v}: must be {range}"))
        };
        if !(1..=64).contains(&self.depth) {
            return bad("depth", "in 1..=64", &self.depth);
        }
        if self.skip && self.depth < 2 {
            return bad(
                "depth",
                ">= 2 with skip (the skip follows layer depth / 2)",
                &1,
            );
        }
        if !(1..=4096).contains(&self.width) {
            return bad("width", "in 1..=4096", &self.width);
        }
        if self.x_freqs > 16 {
            return bad("x_freqs", "in 0..=16", &self.x_freqs);
        }
        if self.t_freqs > 16 {
            return bad("t_freqs", "in 0..=16", &self.t_freqs);
        }
        if self.time_width > 4096 {
            return bad("time_width", "in 0..=4096", &self.time_width);
        }
        if self.time_width > 0 && !(1..=4096).contains(&self.time_out) {
            return bad("time_out", "in 1..=4096", &self.time_out);
        }
        if self.sh_degree > 3 {
            return bad("sh_degree", "in 0..=3", &self.sh_degree);
        }
        let g = &self.group_flow;
        if g.groups > 0 && g.at < self.warm_up {
            return bad(
                "group_flow.at",
                &format!(
                    ">= warm_up = {} (the groups follow the MLP's motion)",
                    self.warm_up
                ),
                &g.at,
            );
        }
        if g.groups > 1_000_000 {
            return bad("group_flow.groups", "in 0..=1000000", &g.groups);
        }
        if g.max_knots < 2 {
            return bad("group_flow.max_knots", ">= 2", &g.max_knots);
        }
        let l = &self.lr;
        if l.position_max_steps == 0 {
            return bad("lr.position_max_steps", ">= 1", &0);
        }
        if l.deform_max_steps == 0 {
            return bad("lr.deform_max_steps", ">= 1", &0);
        }
        let non_negative = [
            ("spatial_lr_scale", self.spatial_lr_scale),
            ("lr.position_init", l.position_init),
            ("lr.position_final", l.position_final),
            ("lr.deform_init", l.deform_init),
            ("lr.deform_final", l.deform_final),
            ("lr.feature", l.feature),
            ("lr.opacity", l.opacity),
            ("lr.scaling", l.scaling),
            ("lr.rotation", l.rotation),
            ("group_flow.node_lr", g.node_lr),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "a finite number >= 0", &v);
            }
        }
        Ok(())
    }
}
