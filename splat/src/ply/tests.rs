//! Tests of the PLY reader and writer: round trips at every SH degree, the channel-major
//! `f_rest` layout, errors naming the file and property, and the baked export.

#![allow(clippy::unwrap_used)]

use super::*;

fn scene(deg: usize) -> Gaussians {
    let k = crate::sh::num_coeffs(deg);
    let n = 5;
    let f = |len: usize, s: f32| {
        Tensor::from_vec(
            (0..len).map(|i| (i as f32 * 0.37 + s).sin()).collect(),
            &[len],
        )
    };
    Gaussians {
        means: f(3 * n, 0.1).reshaped(&[n, 3]),
        log_scales: f(3 * n, 0.2).reshaped(&[n, 3]),
        quats: f(4 * n, 0.3).reshaped(&[n, 4]),
        raw_opacity: f(n, 0.4),
        sh: f(3 * n * k, 0.5).reshaped(&[n, k, 3]),
        sh_degree: deg,
    }
}

fn tmp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("maaf-splat-ply-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn round_trip_every_degree() {
    for deg in 0..=3 {
        let g = scene(deg);
        let p = tmp(&format!("rt{deg}.ply"));
        write_ply(&p, &g).unwrap();
        let back = read_ply(&p).unwrap();
        assert_eq!(back, g, "degree {deg}");
    }
}

#[test]
fn f_rest_is_channel_major() {
    let g = scene(1);
    let bytes = ply_bytes(&g);
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let vals: Vec<f32> = bytes[header_end..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    // Row 0: x y z nx ny nz dc0 dc1 dc2 f_rest_0..8 ...; f_rest_1 is channel 0,
    // coefficient 2.
    assert_eq!(vals[9 + 1], g.sh.data()[2 * 3]);
    // f_rest_3 is channel 1, coefficient 1.
    assert_eq!(vals[9 + 3], g.sh.data()[3 + 1]);
}

#[test]
fn errors_name_file_and_property() {
    let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\nproperty float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nend_header\n0 0 0 0 0 0 0 0 0 0 1 0 0\n";
    let p = tmp("missing.ply");
    std::fs::write(&p, text).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("missing.ply") && e.contains("rot_3"), "{e}");

    let p = tmp("nan.ply");
    std::fs::write(
        &p,
        text.replace(
            "property float rot_2\n",
            "property float rot_2\nproperty float rot_3\n",
        )
        .replace(
            "0 0 0 0 0 0 0 0 0 0 1 0 0\n",
            "0 0 0 0 0 0 nan 0 0 0 1 0 0 0\n",
        ),
    )
    .unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("nan.ply") && e.contains("opacity"), "{e}");

    let g = scene(0);
    let mut bytes = ply_bytes(&g);
    bytes.truncate(bytes.len() - 10);
    let p = tmp("short.ply");
    std::fs::write(&p, bytes).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("short.ply") && e.contains("vertex"), "{e}");

    let e = read_ply(&tmp("absent.ply")).unwrap_err().to_string();
    assert!(e.contains("absent.ply"), "{e}");
}

#[test]
fn baked_export_folds_the_filter() {
    let g = scene(0);
    let var = vec![0.01f32; g.len()];
    let b = g.with_3d_filter(&var);
    for i in 0..g.len() {
        let mut ratio = 1.0;
        for j in 0..3 {
            let s = g.log_scales.data()[3 * i + j].exp();
            let sb = b.log_scales.data()[3 * i + j].exp();
            assert!((sb * sb - (s * s + 0.01)).abs() < 1e-5);
            ratio *= s * s / (s * s + 0.01);
        }
        let o = g.opacities().data()[i] * f32::sqrt(ratio);
        assert!((b.opacities().data()[i] - o).abs() < 1e-5);
    }
    let p = tmp("baked.ply");
    write_baked_ply(&p, &g, &var).unwrap();
    assert_eq!(read_ply(&p).unwrap(), b);
}
