//! The initial point cloud a data set may ship: `points3d.ply` in its folder, the
//! file 3DGS-family loaders look for beside D-NeRF's transforms (3DGS and SaRO-GS
//! `readNerfSyntheticInfo`: `points3d.ply`, random points when it is absent). For a
//! multi-view video it holds the merged per-frame points with their time, as
//! SpacetimeGS's preparation writes them (property `t`).
//!
//! Vertex properties: `x y z` (required), `red green blue` (`uchar` 0-255 or float
//! 0-1; grey 0.5 when absent), `t` (optional, the time of the frame the point was
//! seen at). Other properties (normals) are ignored.

use std::path::Path;

use super::error::DataError;
use crate::PointCloud;

/// File name of a data set's initial point cloud.
pub const POINTS_FILE: &str = "points3d.ply";

/// Reads a point cloud PLY (module doc); errors name the file and the property or
/// vertex at fault.
pub fn read_points(path: &Path) -> Result<PointCloud, DataError> {
    let table = maaf_splat::read_vertex_table(path).map_err(|e| {
        DataError::request(
            path,
            e.to_string().replace(&format!("{}: ", path.display()), ""),
        )
    })?;
    let col = |name: &str| table.column(name);
    let (Some(x), Some(y), Some(z)) = (col("x"), col("y"), col("z")) else {
        return Err(DataError::field(
            path,
            "vertex",
            "needs properties x, y and z",
        ));
    };
    let rgb = match (col("red"), col("green"), col("blue")) {
        (Some(r), Some(g), Some(b)) => Some([r, g, b]),
        (None, None, None) => None,
        _ => {
            return Err(DataError::field(
                path,
                "vertex",
                "has some but not all of red, green, blue",
            ));
        }
    };
    let t = col("t");
    let mut cloud = PointCloud {
        points: Vec::with_capacity(table.rows.len()),
        colours: Vec::with_capacity(table.rows.len()),
        times: t.map(|_| Vec::with_capacity(table.rows.len())),
    };
    for (i, row) in table.rows.iter().enumerate() {
        let value = |c: usize| -> Result<f64, DataError> {
            let v = row[c];
            if v.is_finite() {
                Ok(f64::from(v))
            } else {
                Err(DataError::field(
                    path,
                    table.names[c].clone(),
                    format!("vertex {i}: {v} is not finite"),
                ))
            }
        };
        cloud.points.push([value(x)?, value(y)?, value(z)?]);
        let colour = match rgb {
            Some(cols) => {
                let mut c = [0.0; 3];
                for (k, &ci) in cols.iter().enumerate() {
                    let v = value(ci)?;
                    c[k] = if table.integer[ci] { v / 255.0 } else { v };
                    if !(0.0..=1.0).contains(&c[k]) {
                        return Err(DataError::field(
                            path,
                            table.names[ci].clone(),
                            format!("vertex {i}: {v} is outside 0-255 (uchar) or 0-1 (float)"),
                        ));
                    }
                }
                c
            }
            None => [0.5; 3],
        };
        cloud.colours.push(colour);
        if let (Some(tc), Some(times)) = (t, cloud.times.as_mut()) {
            times.push(value(tc)?);
        }
    }
    if cloud.is_empty() {
        return Err(DataError::field(path, "vertex", "has no points"));
    }
    Ok(cloud)
}

/// A point cloud as a `binary_little_endian` PLY: `x y z` float, `red green blue`
/// uchar (rounded from 0-1), and `t` float when the cloud has times.
pub fn encode_points(cloud: &PointCloud) -> Vec<u8> {
    let n = cloud.len();
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n{}end_header\n",
        if cloud.times.is_some() {
            "property float t\n"
        } else {
            ""
        }
    )
    .into_bytes();
    for i in 0..n {
        for v in cloud.points[i] {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        }
        for c in cloud.colours[i] {
            out.push((c.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
        if let Some(times) = &cloud.times {
            out.extend_from_slice(&(times[i] as f32).to_le_bytes());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("maaf_points_{}_{name}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp");
        dir.join(POINTS_FILE)
    }

    #[test]
    fn binary_points_with_times_round_trip() {
        let cloud = PointCloud {
            points: vec![[0.5, -1.25, 2.0], [3.0, 0.0, -0.125]],
            colours: vec![[1.0, 0.0, 128.0 / 255.0], [0.2, 0.4, 0.6]],
            times: Some(vec![0.25, 1.0]),
        };
        let path = tmp("round_trip");
        std::fs::write(&path, encode_points(&cloud)).expect("write");
        let back = read_points(&path).expect("read");
        assert_eq!(back.points, cloud.points);
        assert_eq!(back.times, cloud.times);
        for (a, b) in back
            .colours
            .iter()
            .flatten()
            .zip(cloud.colours.iter().flatten())
        {
            assert!((a - b).abs() <= 0.5 / 255.0, "{a} vs {b}");
        }
    }

    #[test]
    fn ascii_points_without_colours_or_times_and_bad_files() {
        let path = tmp("ascii");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nend_header\n1 2 3 0\n-1 0.5 4 0\n",
        )
        .expect("write");
        let cloud = read_points(&path).expect("read");
        assert_eq!(cloud.points, vec![[1.0, 2.0, 3.0], [-1.0, 0.5, 4.0]]);
        assert_eq!(cloud.colours, vec![[0.5; 3]; 2]);
        assert_eq!(cloud.times, None);
        let bad = |body: &str, want: &str| {
            std::fs::write(&path, body).expect("write");
            let err = read_points(&path).expect_err("must fail").to_string();
            assert!(err.contains(POINTS_FILE) && err.contains(want), "{err}");
        };
        bad(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
            "x, y and z",
        );
        bad(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nend_header\n1 2 3 0.5\n",
            "not all of red",
        );
        bad(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nproperty float green\nproperty float blue\nend_header\n1 2 3 0.5 2 0\n",
            "green",
        );
        bad(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 nan 3\n",
            "not finite",
        );
        bad(
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
            "no points",
        );
        bad(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
            "3 rows",
        );
    }
}
