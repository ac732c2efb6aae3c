//! The standard 3DGS PLY (Inria layout): read with `serde-ply`, written by hand as
//! `binary_little_endian` (docs/conventions.md).
//!
//! One `vertex` element with float properties `x y z nx ny nz f_dc_0..2
//! f_rest_0..(3(K-1)-1) opacity scale_0..2 rot_0..3`: opacity is a logit, scales are
//! logs, the rotation is `(w, x, y, z)`. `f_rest` is channel-major: property
//! `f_rest_{c (K-1) + (k-1)}` holds SH coefficient `k >= 1` of channel `c`
//! (Inria `save_ply` flattens `features_rest` transposed to `[N, 3, K-1]`). Normals are
//! optional on read and written as zeros; extra properties are ignored on read.

use std::io::BufReader;
use std::path::Path;

use maaf_autodiff::Tensor;
use serde::Deserialize;
use serde::de::{IgnoredAny, MapAccess, Visitor};

use crate::gaussians::Gaussians;

/// Errors of PLY reading and writing; each names the file and, where it applies,
/// the property.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// File that failed.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The header or data could not be parsed (truncated file, wrong count, bad type).
    #[error("{path}: invalid PLY: {message}")]
    Format {
        /// File that failed.
        path: String,
        /// What is wrong.
        message: String,
    },
    /// A required property is absent from the `vertex` element.
    #[error("{path}: missing property `{property}` in element `vertex`")]
    MissingProperty {
        /// File that failed.
        path: String,
        /// Missing property name.
        property: String,
    },
    /// A property value is NaN or infinite.
    #[error("{path}: property `{property}` of vertex {row} is not finite ({value})")]
    NonFinite {
        /// File that failed.
        path: String,
        /// Offending property.
        property: String,
        /// Vertex index.
        row: usize,
        /// The value read.
        value: f32,
    },
}

/// One row as the values of its properties, in header order.
struct Row(Vec<f32>);

impl<'de> Deserialize<'de> for Row {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct RowVisitor;
        impl<'de> Visitor<'de> for RowVisitor {
            type Value = Row;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a PLY row of scalar properties")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Row, A::Error> {
                let mut values = Vec::with_capacity(64);
                while map.next_key::<IgnoredAny>()?.is_some() {
                    values.push(map.next_value::<f32>()?);
                }
                Ok(Row(values))
            }
        }
        d.deserialize_map(RowVisitor)
    }
}

/// The `vertex` row of a 3DGS PLY with `k` SH coefficients per channel: the one
/// place that fixes the property names and their order, for reading and writing.
///
/// `x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 f_rest_0..f_rest_{3(k-1)-1} opacity scale_0
/// scale_1 scale_2 rot_0 rot_1 rot_2 rot_3` (Inria `construct_list_of_attributes`).
#[derive(Clone, Copy, Debug)]
struct Layout {
    k: usize,
}

impl Layout {
    const MEAN: usize = 0;
    const NORMAL: usize = 3;
    const DC: usize = 6;
    const REST: usize = 9;

    fn opacity(self) -> usize {
        Self::REST + 3 * (self.k - 1)
    }

    fn scale(self) -> usize {
        self.opacity() + 1
    }

    fn rot(self) -> usize {
        self.opacity() + 4
    }

    fn len(self) -> usize {
        self.opacity() + 8
    }

    /// Row position of SH coefficient `kk` (0 = DC) of channel `c`; `f_rest` is
    /// channel-major.
    fn sh(self, kk: usize, c: usize) -> usize {
        if kk == 0 {
            Self::DC + c
        } else {
            Self::REST + c * (self.k - 1) + (kk - 1)
        }
    }

    /// Property names in row order.
    fn names(self) -> Vec<String> {
        let mut names: Vec<String> = ["x", "y", "z", "nx", "ny", "nz"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        names.extend((0..3).map(|c| format!("f_dc_{c}")));
        names.extend((0..3 * (self.k - 1)).map(|i| format!("f_rest_{i}")));
        names.push("opacity".into());
        names.extend((0..3).map(|i| format!("scale_{i}")));
        names.extend((0..4).map(|i| format!("rot_{i}")));
        debug_assert_eq!(names.len(), self.len());
        names
    }

    /// Whether the property at row position `j` may be absent on read (the normals,
    /// which 3DGS writes as zeros and never reads).
    fn optional(j: usize) -> bool {
        (Self::NORMAL..Self::NORMAL + 3).contains(&j)
    }

    /// Gaussian `i` of `g` as a row (normals zero).
    fn pack(self, g: &Gaussians, i: usize) -> Vec<f32> {
        let mut row = vec![0.0f32; self.len()];
        let shk = g.sh.shape()[1];
        row[Self::MEAN..Self::MEAN + 3].copy_from_slice(&g.means.data()[3 * i..3 * i + 3]);
        for kk in 0..self.k {
            for c in 0..3 {
                row[self.sh(kk, c)] = g.sh.data()[(i * shk + kk) * 3 + c];
            }
        }
        row[self.opacity()] = g.raw_opacity.data()[i];
        row[self.scale()..self.scale() + 3].copy_from_slice(&g.log_scales.data()[3 * i..3 * i + 3]);
        row[self.rot()..self.rot() + 4].copy_from_slice(&g.quats.data()[4 * i..4 * i + 4]);
        row
    }

    /// Appends a row to the column buffers of a scene (`sh` holds `k` coefficients).
    fn unpack(self, row: &[f32], out: &mut Columns) {
        out.means
            .extend_from_slice(&row[Self::MEAN..Self::MEAN + 3]);
        for kk in 0..self.k {
            for c in 0..3 {
                out.sh.push(row[self.sh(kk, c)]);
            }
        }
        out.raw_opacity.push(row[self.opacity()]);
        out.log_scales
            .extend_from_slice(&row[self.scale()..self.scale() + 3]);
        out.quats
            .extend_from_slice(&row[self.rot()..self.rot() + 4]);
    }
}

/// Flat buffers of a scene being read, in [`Gaussians`] order.
#[derive(Default)]
struct Columns {
    means: Vec<f32>,
    log_scales: Vec<f32>,
    quats: Vec<f32>,
    raw_opacity: Vec<f32>,
    sh: Vec<f32>,
}

/// The `vertex` element of a PLY file (ascii or binary): property names in header
/// order, whether each is an integer type (e.g. `uchar` colours), and every row's
/// values converted to `f32`. The generic reader behind [`read_ply`] and the point
/// clouds data sets ship; list properties are refused.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexTable {
    /// Property names, header order.
    pub names: Vec<String>,
    /// Whether each property has an integer type.
    pub integer: Vec<bool>,
    /// One entry per vertex, one value per property.
    pub rows: Vec<Vec<f32>>,
    /// The header's `comment` lines, without the keyword, in order.
    pub comments: Vec<String>,
}

impl VertexTable {
    /// Column of property `name`, if present.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|p| p == name)
    }
}

/// Reads the `vertex` element of the PLY file at `path` ([`VertexTable`]); errors
/// name the file and what is wrong (no vertex element, a list property, a row count
/// that differs from the header's).
pub fn read_vertex_table(path: &Path) -> Result<VertexTable, PlyError> {
    let shown = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| PlyError::Io {
        path: shown.clone(),
        source,
    })?;
    let format = |message: String| PlyError::Format {
        path: shown.clone(),
        message,
    };
    let mut reader = serde_ply::PlyReader::from_reader(BufReader::new(file))
        .map_err(|e| format(format!("header: {e}")))?;
    let comments = reader.header().comments.clone();
    let elements: Vec<String> = reader
        .header()
        .elem_defs
        .iter()
        .map(|e| e.name.clone())
        .collect();
    let Some(vi) = elements.iter().position(|e| e == "vertex") else {
        return Err(format("no element `vertex`".into()));
    };
    for name in &elements[..vi] {
        reader
            .next_element::<IgnoredAny>()
            .map_err(|e| format(format!("element `{name}`: {e}")))?;
    }
    let def = reader
        .current_element()
        .ok_or_else(|| format("no element `vertex`".into()))?
        .clone();
    let mut integer = Vec::with_capacity(def.properties.len());
    for p in &def.properties {
        match &p.property_type {
            serde_ply::PropertyType::Scalar(t) => integer.push(!matches!(
                t,
                serde_ply::ScalarType::F32 | serde_ply::ScalarType::F64
            )),
            serde_ply::PropertyType::List { .. } => {
                return Err(format(format!(
                    "property `{}` of element `vertex` is a list; only scalars are read",
                    p.name
                )));
            }
        }
    }
    let names: Vec<String> = def.properties.iter().map(|p| p.name.clone()).collect();
    let rows: Vec<Row> = reader.next_element().map_err(|e| {
        format(format!(
            "element `vertex` ({} rows declared): {e}",
            def.count
        ))
    })?;
    if rows.len() != def.count {
        return Err(format(format!(
            "element `vertex` declares {} rows, read {}",
            def.count,
            rows.len()
        )));
    }
    for (i, row) in rows.iter().enumerate() {
        if row.0.len() != names.len() {
            return Err(format(format!(
                "vertex {i} has {} values for {} properties",
                row.0.len(),
                names.len()
            )));
        }
    }
    Ok(VertexTable {
        names,
        integer,
        rows: rows.into_iter().map(|r| r.0).collect(),
        comments,
    })
}

/// Reads a 3DGS PLY file (ascii or binary) into [`Gaussians`]. The SH degree is
/// inferred from the number of `f_rest_*` properties (0, 9, 24 or 45).
pub fn read_ply(path: &Path) -> Result<Gaussians, PlyError> {
    read_ply_with_comments(path).map(|(g, _)| g)
}

/// [`read_ply`] with the header's `comment` lines (without the keyword), where a
/// writer may have recorded how the scene is to be drawn.
pub fn read_ply_with_comments(path: &Path) -> Result<(Gaussians, Vec<String>), PlyError> {
    let shown = path.display().to_string();
    let format = |message: String| PlyError::Format {
        path: shown.clone(),
        message,
    };
    let table = read_vertex_table(path)?;
    let n_rest = table
        .names
        .iter()
        .filter(|p| p.starts_with("f_rest_"))
        .count();
    let degree = match n_rest {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        other => {
            return Err(format(format!(
                "{other} `f_rest_*` properties; expected 0, 9, 24 or 45 (SH degree 0-3)"
            )));
        }
    };
    let layout = Layout {
        k: crate::sh::num_coeffs(degree),
    };
    let names = layout.names();
    let mut column = Vec::with_capacity(names.len());
    for (j, name) in names.iter().enumerate() {
        match table.column(name) {
            Some(c) => column.push(Some(c)),
            None if Layout::optional(j) => column.push(None),
            None => {
                return Err(PlyError::MissingProperty {
                    path: shown.clone(),
                    property: name.clone(),
                });
            }
        }
    }
    let n = table.rows.len();
    let mut cols = Columns::default();
    let mut values = vec![0.0f32; layout.len()];
    for (i, row) in table.rows.iter().enumerate() {
        for (j, c) in column.iter().enumerate() {
            let v = c.map_or(0.0, |c| row[c]);
            if !v.is_finite() {
                return Err(PlyError::NonFinite {
                    path: shown.clone(),
                    property: names[j].clone(),
                    row: i,
                    value: v,
                });
            }
            values[j] = v;
        }
        layout.unpack(&values, &mut cols);
    }
    let gaussians = Gaussians {
        means: Tensor::from_vec(cols.means, &[n, 3]),
        log_scales: Tensor::from_vec(cols.log_scales, &[n, 3]),
        quats: Tensor::from_vec(cols.quats, &[n, 4]),
        raw_opacity: Tensor::from_vec(cols.raw_opacity, &[n]),
        sh: Tensor::from_vec(cols.sh, &[n, layout.k, 3]),
        sh_degree: degree,
    };
    Ok((gaussians, table.comments))
}

/// Encodes `g` as a `binary_little_endian` 3DGS PLY.
pub fn ply_bytes(g: &Gaussians) -> Vec<u8> {
    ply_bytes_with_comments(g, &[])
}

/// [`ply_bytes`] with one `comment` header line per entry of `comments` (each a single
/// line; 3DGS readers skip comments).
pub fn ply_bytes_with_comments(g: &Gaussians, comments: &[String]) -> Vec<u8> {
    let n = g.len();
    let layout = Layout {
        k: crate::sh::num_coeffs(g.sh_degree),
    };
    let names = layout.names();
    let mut out = Vec::with_capacity(200 + n * names.len() * 4);
    out.extend_from_slice(b"ply\nformat binary_little_endian 1.0\n");
    for c in comments {
        out.extend_from_slice(format!("comment {}\n", c.replace('\n', " ")).as_bytes());
    }
    out.extend_from_slice(format!("element vertex {n}\n").as_bytes());
    for name in &names {
        out.extend_from_slice(format!("property float {name}\n").as_bytes());
    }
    out.extend_from_slice(b"end_header\n");
    for i in 0..n {
        for v in layout.pack(g, i) {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Writes a 3DGS PLY (binary little endian) atomically.
pub fn write_ply(path: &Path, g: &Gaussians) -> Result<(), PlyError> {
    maaf_io::write_atomic(path, &ply_bytes(g)).map_err(|source| PlyError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Writes the "baked" PLY: the 3D filter of per-Gaussian variance `var` folded into
/// scale and opacity ([`Gaussians::with_3d_filter`], Mip-Splatting
/// `save_fused_ply`), so that ordinary 3DGS viewers show the filtered scene.
pub fn write_baked_ply(path: &Path, g: &Gaussians, var: &[f32]) -> Result<(), PlyError> {
    write_ply(path, &g.with_3d_filter(var))
}

#[cfg(test)]
mod tests;
