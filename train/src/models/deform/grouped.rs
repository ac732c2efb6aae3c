//! The GroupFlow stage of a Deformable-3DGS model: the fitted groups, each Gaussian's
//! knot-0 offset, their checkpoint buffers, and the grouped deformation on a tape
//! (formula in the module docs of [`super`]).

use std::sync::Arc;

use glam::{DMat3, DQuat, DVec3};
use maaf_autodiff::ops::concat;
use maaf_autodiff::{Float, Tensor, Var};

use super::group_flow::GroupFlow;

/// Fitted groups plus each Gaussian's offset `o` from its stored centre to its knot-0
/// position when the groups were fitted. Every value is held at the precision of the
/// model's float type, so a checkpoint restores it bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct Grouped {
    /// Groups and their motion.
    pub flow: GroupFlow,
    /// Knot-0 offset of each Gaussian \[N].
    pub offset0: Vec<DVec3>,
}

impl Grouped {
    /// Names of the checkpoint buffers, sorted.
    pub const BUFFERS: [&'static str; 5] = [
        "group_flow/labels",
        "group_flow/nodes",
        "group_flow/offset0",
        "group_flow/rotations",
        "group_flow/translations",
    ];

    /// Fits `groups` groups to the deformed centres `centres[k]` \[N,3] at the knots,
    /// for the stored centres `stored` \[N,3].
    pub fn fit<T: Float>(stored: &Tensor<T>, centres: &[Tensor<T>], groups: usize) -> Self {
        let trajectories: Vec<Vec<DVec3>> = centres.iter().map(points).collect();
        let offset0 = trajectories[0]
            .iter()
            .zip(points(stored))
            .map(|(p, x)| *p - x)
            .collect();
        let mut g = Grouped {
            flow: GroupFlow::fit(&trajectories, groups),
            offset0,
        };
        let round = |v: f64| T::of(v).to_f64();
        let round3 = |v: DVec3| DVec3::new(round(v.x), round(v.y), round(v.z));
        let f = &mut g.flow;
        f.nodes.iter_mut().for_each(|v| *v = round3(*v));
        f.translations.iter_mut().for_each(|v| *v = round3(*v));
        f.rotations
            .iter_mut()
            .for_each(|q| *q = DQuat::from_xyzw(round(q.x), round(q.y), round(q.z), round(q.w)));
        g.offset0.iter_mut().for_each(|v| *v = round3(*v));
        g
    }

    /// Stored scalars: labels, offsets, nodes and the knots' rotations and translations.
    pub fn num_scalars(&self) -> usize {
        let f = &self.flow;
        4 * f.labels.len() + 3 * f.groups() + 7 * f.groups() * f.knots
    }

    /// Keeps rows `index` (see [`GroupFlow::select_rows`]).
    pub fn select_rows(&mut self, index: &[usize]) {
        self.flow.select_rows(index);
        self.offset0 = index.iter().map(|&i| self.offset0[i]).collect();
    }

    /// The checkpoint buffers, named as [`Grouped::BUFFERS`]: labels \[N], nodes \[G,3],
    /// offsets \[N,3], rotations \[G,K,4] (x, y, z, w) and translations \[G,K,3].
    pub fn to_buffers<T: Float>(&self) -> Vec<(String, Tensor<T>)> {
        let f = &self.flow;
        let (g, k) = (f.groups(), f.knots);
        let flat3 =
            |v: &[DVec3]| -> Vec<T> { v.iter().flat_map(|p| p.to_array().map(T::of)).collect() };
        let labels = f.labels.iter().map(|&l| T::of(l as f64)).collect();
        let rotations = f
            .rotations
            .iter()
            .flat_map(|q| q.to_array().map(T::of))
            .collect();
        let tensors = [
            Tensor::from_vec(labels, &[f.labels.len()]),
            Tensor::from_vec(flat3(&f.nodes), &[g, 3]),
            Tensor::from_vec(flat3(&self.offset0), &[self.offset0.len(), 3]),
            Tensor::from_vec(rotations, &[g, k, 4]),
            Tensor::from_vec(flat3(&f.translations), &[g, k, 3]),
        ];
        Self::BUFFERS
            .iter()
            .map(|s| s.to_string())
            .zip(tensors)
            .collect()
    }

    /// Rebuilds the stage from the five buffers of [`Grouped::to_buffers`] for a model
    /// of `n` Gaussians; an error names the buffer whose shape or value is wrong.
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
        let [labels_n, nodes_n, offset_n, rot_n, trans_n] = Self::BUFFERS;
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
}

impl<'t, T: Float> GroupMotion<'t, T> {
    /// Binds the stage for stored centres `stored` \[N,3] and the node-offset parameter
    /// (at least G rows; the first G are used).
    pub(super) fn new(grouped: Arc<Grouped>, stored: &Tensor<T>, node_offsets: Var<'t, T>) -> Self {
        let g = grouped.flow.groups();
        GroupMotion {
            grouped,
            stored: points(stored),
            node_offsets: node_offsets.slice(0, 0, g),
        }
    }

    /// `mu(t) - x` \[N,3]: the constant `R_g (sg(x) + o - c_g) + c_g + T_g - sg(x)`
    /// (fitted centroid `c_g`) plus the trained part `(I - R_g) delta_g` of the node
    /// `n_g = c_g + delta_g`.
    pub(super) fn displacement(&self, time: f64) -> Var<'t, T> {
        let f = &self.grouped.flow;
        let g = f.groups();
        let motions: Vec<(DQuat, DVec3)> = (0..g).map(|k| f.motion(k, time)).collect();
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
        let m = tape.constant(Tensor::from_vec(i_minus_r, &[g, 9]));
        let cols: Vec<Var<'t, T>> = (0..3)
            .map(|a| {
                (m.slice(1, 3 * a, 3 * a + 3) * self.node_offsets)
                    .sum_axis(1)
                    .reshape(&[g, 1])
            })
            .collect();
        let trained = concat(&cols, 1).gather_rows(&f.labels);
        tape.constant(Tensor::from_vec(fixed, &[f.labels.len(), 3])) + trained
    }
}

/// Rows of an \[N,3] tensor as points.
fn points<T: Float>(t: &Tensor<T>) -> Vec<DVec3> {
    t.data()
        .chunks_exact(3)
        .map(|p| DVec3::new(p[0].to_f64(), p[1].to_f64(), p[2].to_f64()))
        .collect()
}
