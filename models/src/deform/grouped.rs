//! The GroupFlow stage of a Deformable-3DGS model: the fitted groups, what the MLP
//! added to each Gaussian at knot 0, their checkpoint buffers, and the grouped
//! deformation on a tape (formulas in the module docs of [`super`]).

use std::sync::Arc;

use glam::{DMat3, DQuat, DVec3};
use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Tensor, Var};

use super::group_flow::GroupFlow;

/// Fitted groups plus what the MLP added to each Gaussian at knot 0 (t = 0) when the
/// groups were fitted: the centre offset `o`, the scale residual `ds_0` and the
/// quaternion residual `dq_0`. Every value is held at the precision of the model's
/// float type, so a checkpoint restores it bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct Grouped {
    /// Groups and their motion.
    pub flow: GroupFlow,
    /// Knot-0 centre offset of each Gaussian \[N].
    pub offset0: Vec<DVec3>,
    /// Knot-0 scale residual \[N] (added to the activated scale).
    pub scale0: Vec<DVec3>,
    /// Knot-0 quaternion residual \[N] (w, x, y, z; added to the unit quaternion).
    pub quat0: Vec<[f64; 4]>,
}

/// The stored values and what the MLP makes of them at t = 0 (\[N,3] or \[N,4] each):
/// the input of [`Grouped::fit`] besides the trajectories.
pub struct KnotZero<'a, T: Float> {
    /// Stored centres.
    pub stored: &'a Tensor<T>,
    /// Activated scales.
    pub scales: &'a Tensor<T>,
    /// Unit quaternions.
    pub unit_quats: &'a Tensor<T>,
    /// Deformed scales at t = 0.
    pub scales_at_0: &'a Tensor<T>,
    /// Deformed quaternions at t = 0.
    pub quats_at_0: &'a Tensor<T>,
}

impl Grouped {
    /// Names of the checkpoint buffers, sorted.
    pub const BUFFERS: [&'static str; 7] = [
        "group_flow/labels",
        "group_flow/nodes",
        "group_flow/offset0",
        "group_flow/quat0",
        "group_flow/rotations",
        "group_flow/scale0",
        "group_flow/translations",
    ];

    /// Fits `groups` groups to the deformed centres `centres[k]` \[N,3] at the knots
    /// and keeps the MLP's knot-0 residuals from `at0`.
    pub fn fit<T: Float>(at0: &KnotZero<'_, T>, centres: &[Tensor<T>], groups: usize) -> Self {
        let trajectories: Vec<Vec<DVec3>> = centres.iter().map(points).collect();
        let minus = |a: &[DVec3], b: Vec<DVec3>| a.iter().zip(b).map(|(p, q)| *p - q).collect();
        let quat0 = at0
            .quats_at_0
            .data()
            .chunks_exact(4)
            .zip(at0.unit_quats.data().chunks_exact(4))
            .map(|(d, u)| std::array::from_fn(|j| d[j].to_f64() - u[j].to_f64()))
            .collect();
        let mut g = Grouped {
            offset0: minus(&trajectories[0], points(at0.stored)),
            scale0: minus(&points(at0.scales_at_0), points(at0.scales)),
            quat0,
            flow: GroupFlow::fit(&trajectories, groups),
        };
        let round = |v: f64| T::of(v).to_f64();
        let round3 = |v: DVec3| DVec3::new(round(v.x), round(v.y), round(v.z));
        let f = &mut g.flow;
        f.nodes.iter_mut().for_each(|v| *v = round3(*v));
        f.translations.iter_mut().for_each(|v| *v = round3(*v));
        for q in f.rotations.iter_mut() {
            *q = DQuat::from_xyzw(round(q.x), round(q.y), round(q.z), round(q.w));
        }
        g.offset0.iter_mut().for_each(|v| *v = round3(*v));
        g.scale0.iter_mut().for_each(|v| *v = round3(*v));
        g.quat0.iter_mut().for_each(|q| *q = q.map(round));
        g
    }

    /// Stored scalars: labels, knot-0 residuals, nodes and the knots' rotations and
    /// translations.
    pub fn num_scalars(&self) -> usize {
        let f = &self.flow;
        11 * f.labels.len() + 3 * f.groups() + 7 * f.groups() * f.knots
    }

    /// Keeps rows `index` (see [`GroupFlow::select_rows`]).
    pub fn select_rows(&mut self, index: &[usize]) {
        self.flow.select_rows(index);
        self.offset0 = index.iter().map(|&i| self.offset0[i]).collect();
        self.scale0 = index.iter().map(|&i| self.scale0[i]).collect();
        self.quat0 = index.iter().map(|&i| self.quat0[i]).collect();
    }

    /// The checkpoint buffers, named as [`Grouped::BUFFERS`]: labels \[N], nodes \[G,3],
    /// offsets \[N,3], quaternion residuals \[N,4], rotations \[G,K,4] (x, y, z, w),
    /// scale residuals \[N,3] and translations \[G,K,3].
    pub fn to_buffers<T: Float>(&self) -> Vec<(String, Tensor<T>)> {
        let f = &self.flow;
        let (g, k, n) = (f.groups(), f.knots, f.labels.len());
        let flat3 =
            |v: &[DVec3]| -> Vec<T> { v.iter().flat_map(|p| p.to_array().map(T::of)).collect() };
        let labels = f.labels.iter().map(|&l| T::of(l as f64)).collect();
        let rotations = f.rotations.iter().flat_map(|q| q.to_array().map(T::of));
        let quat0 = self.quat0.iter().flat_map(|q| q.map(T::of)).collect();
        let tensors = [
            Tensor::from_vec(labels, &[n]),
            Tensor::from_vec(flat3(&f.nodes), &[g, 3]),
            Tensor::from_vec(flat3(&self.offset0), &[n, 3]),
            Tensor::from_vec(quat0, &[n, 4]),
            Tensor::from_vec(rotations.collect(), &[g, k, 4]),
            Tensor::from_vec(flat3(&self.scale0), &[n, 3]),
            Tensor::from_vec(flat3(&f.translations), &[g, k, 3]),
        ];
        Self::BUFFERS
            .iter()
            .map(|s| s.to_string())
            .zip(tensors)
            .collect()
    }

    /// Rebuilds the stage from the buffers of [`Grouped::to_buffers`] for a model of
    /// `n` Gaussians; an error names the buffer whose shape or value is wrong.
    pub fn from_buffers<T: Float>(
        buffers: Vec<(String, Tensor<T>)>,
        n: usize,
    ) -> Result<Self, String> {
        let get = |name: &str| -> Result<Vec<f64>, String> {
            buffers
                .iter()
                .find(|(b, _)| b == name)
                .map(|(_, t)| t.data().iter().map(|&v| Float::to_f64(v)).collect())
                .ok_or_else(|| format!("buffer `{name}` missing"))
        };
        let shape_of = |name: &str| -> Vec<usize> {
            buffers
                .iter()
                .find(|(b, _)| b == name)
                .map_or_else(Vec::new, |(_, t)| t.shape().to_vec())
        };
        let [
            labels_n,
            nodes_n,
            offset_n,
            quat0_n,
            rot_n,
            scale0_n,
            trans_n,
        ] = Self::BUFFERS;
        let nodes = shape_of(nodes_n);
        let rot = shape_of(rot_n);
        let (g, k) = match (nodes.as_slice(), rot.as_slice()) {
            ([g, 3], [g2, k, 4]) if g == g2 && *g >= 1 && *k >= 2 => (*g, *k),
            _ => {
                return Err(format!(
                    "buffers `{nodes_n}` {nodes:?} and `{rot_n}` {rot:?}: expected [G,3] and [G,K,4] with G >= 1, K >= 2"
                ));
            }
        };
        let expect = |name: &str, shape: &[usize]| -> Result<(), String> {
            let got = shape_of(name);
            if got == shape {
                Ok(())
            } else {
                Err(format!(
                    "buffer `{name}` has shape {got:?}, expected {shape:?}"
                ))
            }
        };
        expect(labels_n, &[n])?;
        expect(offset_n, &[n, 3])?;
        expect(quat0_n, &[n, 4])?;
        expect(scale0_n, &[n, 3])?;
        expect(trans_n, &[g, k, 3])?;
        let labels = get(labels_n)?
            .into_iter()
            .map(|v| {
                let l = v as usize;
                if v >= 0.0 && v.fract() == 0.0 && l < g {
                    Ok(l)
                } else {
                    Err(format!(
                        "buffer `{labels_n}`: label {v} is not a group in 0..{g}"
                    ))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let vec3 =
            |d: Vec<f64>| -> Vec<DVec3> { d.chunks_exact(3).map(DVec3::from_slice).collect() };
        let rotations = get(rot_n)?
            .chunks_exact(4)
            .map(|q| DQuat::from_xyzw(q[0], q[1], q[2], q[3]))
            .collect();
        Ok(Grouped {
            flow: GroupFlow {
                labels,
                nodes: vec3(get(nodes_n)?),
                rotations,
                translations: vec3(get(trans_n)?),
                knots: k,
            },
            offset0: vec3(get(offset_n)?),
            scale0: vec3(get(scale0_n)?),
            quat0: get(quat0_n)?
                .chunks_exact(4)
                .map(|q| [q[0], q[1], q[2], q[3]])
                .collect(),
        })
    }
}

/// The grouped deformation bound on a tape.
pub(super) struct GroupMotion<'t, T: Float> {
    grouped: Arc<Grouped>,
    /// `sg(x)`: the stored centres, constants.
    stored: Vec<DVec3>,
    /// Trained node offsets \[G,3].
    node_offsets: Var<'t, T>,
    /// Whether each Gaussian turns with its group.
    rotate: bool,
    /// `s + ds_0` \[N,3], time-independent.
    scales0: Var<'t, T>,
    /// `q / |q| + dq_0` \[N,4], time-independent.
    quats0: Var<'t, T>,
}

impl<'t, T: Float> GroupMotion<'t, T> {
    /// Binds the stage for stored centres `stored` \[N,3], the node-offset parameter
    /// (at least G rows; the first G are used) and the canonical activated scales and
    /// unit quaternions, to which the knot-0 residuals are added once here.
    pub(super) fn new(
        grouped: Arc<Grouped>,
        stored: &Tensor<T>,
        node_offsets: Var<'t, T>,
        [scales, unit_quats]: [Var<'t, T>; 2],
        rotate: bool,
    ) -> Self {
        let n = grouped.offset0.len();
        let tape = scales.tape();
        let constant = |data: Vec<T>, w: usize| tape.constant(Tensor::from_vec(data, &[n, w]));
        let ds0 = grouped.scale0.iter().flat_map(|v| v.to_array().map(T::of));
        let dq0 = grouped.quat0.iter().flat_map(|q| q.map(T::of));
        let scales0 = scales + constant(ds0.collect(), 3);
        let quats0 = unit_quats + constant(dq0.collect(), 4);
        let g = grouped.flow.groups();
        GroupMotion {
            grouped,
            stored: points(stored),
            node_offsets: node_offsets.slice(0, 0, g),
            rotate,
            scales0,
            quats0,
        }
    }

    /// Each group's rotation and translation at `time`.
    pub(super) fn motions(&self, time: f64) -> Vec<(DQuat, DVec3)> {
        let f = &self.grouped.flow;
        (0..f.groups()).map(|g| f.motion(g, time)).collect()
    }

    /// `mu(t) - x` \[N,3]: the constant `R_g (sg(x) + o - c_g) + c_g + T_g - sg(x)`
    /// (fitted centroid `c_g`) plus the trained part `(I - R_g) delta_g` of the node
    /// `n_g = c_g + delta_g`.
    pub(super) fn displacement(&self, motions: &[(DQuat, DVec3)]) -> Var<'t, T> {
        let f = &self.grouped.flow;
        let fixed: Vec<T> = f
            .labels
            .iter()
            .zip(&self.stored)
            .zip(&self.grouped.offset0)
            .flat_map(|((&l, &x), &o)| {
                let (q, t) = motions[l];
                let c = f.nodes[l];
                (q * (x + o - c) + c + t - x).to_array().map(T::of)
            })
            .collect();
        let i_minus_r: Vec<T> = motions
            .iter()
            .flat_map(|(q, _)| {
                let r = DMat3::from_quat(*q);
                let rows = [r.row(0), r.row(1), r.row(2)];
                (0..9).map(move |e| {
                    let (a, b) = (e / 3, e % 3);
                    T::of(f64::from(u8::from(a == b)) - rows[a][b])
                })
            })
            .collect();
        let tape = self.node_offsets.tape();
        let m = tape.constant(Tensor::from_vec(i_minus_r, &[f.groups(), 9]));
        let trained = row_products(m, self.node_offsets, 3).gather_rows(&f.labels);
        tape.constant(Tensor::from_vec(fixed, &[f.labels.len(), 3])) + trained
    }

    /// Scales and quaternions at the motions' time: `s + ds_0` and
    /// `r_g(t) (q / |q| + dq_0)` (quaternion product with the group's turn `r_g`;
    /// without it when `rotate` is off).
    pub(super) fn shape(&self, motions: &[(DQuat, DVec3)]) -> (Var<'t, T>, Var<'t, T>) {
        if !self.rotate {
            return (self.scales0, self.quats0);
        }
        // Left multiplication by r = (w, x, y, z), as a 4x4 matrix acting on (w, x, y, z).
        let left: Vec<T> = self
            .grouped
            .flow
            .labels
            .iter()
            .flat_map(|&l| {
                let r = motions[l].0;
                let (w, x, y, z) = (r.w, r.x, r.y, r.z);
                [w, -x, -y, -z, x, w, -z, y, y, z, w, -x, z, -y, x, w].map(T::of)
            })
            .collect();
        let n = self.stored.len();
        let left = self
            .quats0
            .tape()
            .constant(Tensor::from_vec(left, &[n, 16]));
        (self.scales0, row_products(left, self.quats0, 4))
    }
}

/// Row by row, the `w` dot products of an \[R, w * w] matrix (row-major per row) with
/// an \[R, w] vector: \[R, w].
fn row_products<'t, T: Float>(m: Var<'t, T>, v: Var<'t, T>, w: usize) -> Var<'t, T> {
    let rows = v.value().rows();
    let cols: Vec<Var<'t, T>> = (0..w)
        .map(|a| {
            (m.slice(1, w * a, w * a + w) * v)
                .sum_axis(1)
                .reshape(&[rows, 1])
        })
        .collect();
    concat(&cols, 1)
}

/// Rows of an \[N,3] tensor as points.
fn points<T: Float>(t: &Tensor<T>) -> Vec<DVec3> {
    t.data()
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0].to_f64(), p[1].to_f64(), p[2].to_f64()))
        .collect()
}
