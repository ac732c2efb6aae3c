//! Temporal stability metrics (paper supplementary): the warp against a slow
//! reference, exact answers on a translating pattern, aggregation, the flow direction
//! of the built-in generator, and bad input.

use maaf_autodiff::Tensor;
use maaf_data::WHITE;
use maaf_data::downsample::{composite_premultiplied, premultiply};
use maaf_data::synthetic::build_scene;
use maaf_data::synthetic::render::{forward_flow, render_rgba};
use maaf_data::synthetic::rig::{camera_at, video_position};
use maaf_eval::metrics::temporal::{TemporalError, temporal_metrics, warp_error, warp_forward};
use maaf_lpips::{Lpips, Net};
use maaf_scene::metrics::ssim;

/// A deterministic pseudo-random value on [0, 1] for integer coordinates (a hash), so
/// that content entering the image is unrelated to what was there.
fn hash01(x: i64, y: i64, c: i64) -> f32 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (c as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// The warp written as a search: for target pixel `p` with valid flow, the source is
/// the one pixel `q` of the next frame whose square `[qx, qx + 1) x [qy, qy + 1)`
/// contains the moved centre `p + 0.5 + flow`; none found keeps frame t.
fn warp_reference(
    next: &[f32],
    cur: &[f32],
    flow: &[f32],
    h: usize,
    w: usize,
    c: usize,
) -> Vec<f32> {
    let mut out = cur.to_vec();
    for y in 0..h {
        for x in 0..w {
            let f = &flow[(y * w + x) * 3..];
            if f[2] != 1.0 {
                continue;
            }
            let (mx, my) = (x as f64 + 0.5 + f[0] as f64, y as f64 + 0.5 + f[1] as f64);
            for qy in 0..h {
                for qx in 0..w {
                    let inside = (qx as f64) <= mx
                        && mx < (qx + 1) as f64
                        && (qy as f64) <= my
                        && my < (qy + 1) as f64;
                    if inside {
                        for ch in 0..c {
                            out[(y * w + x) * c + ch] = next[(qy * w + qx) * c + ch];
                        }
                    }
                }
            }
        }
    }
    out
}

#[test]
fn warp_matches_the_search_reference_on_random_flows() {
    let (h, w, c) = (9, 13, 3);
    let img = |s: i64| -> Vec<f32> { (0..h * w * c).map(|i| hash01(i as i64, s, 0)).collect() };
    let (next, cur) = (img(1), img(2));
    // Flows in 1/64 px steps (the stored precision, so centres land exactly on pixel
    // edges too), up to +-4 px, some invalid, some leaving the image.
    let flow: Vec<f32> = (0..h * w)
        .flat_map(|p| {
            let dx = ((hash01(p as i64, 3, 0) * 512.0).floor() - 256.0) / 64.0;
            let dy = ((hash01(p as i64, 4, 0) * 512.0).floor() - 256.0) / 64.0;
            let valid = if hash01(p as i64, 5, 0) < 0.8 {
                1.0
            } else {
                0.0
            };
            [dx, dy, valid]
        })
        .collect();
    let want = warp_reference(&next, &cur, &flow, h, w, c);
    let t = |v: &[f32], ch: usize| Tensor::from_vec(v.to_vec(), &[h, w, ch]);
    let got = warp_forward(&t(&next, c), &t(&cur, c), &t(&flow, 3)).expect("warp");
    assert_eq!(got.data(), &want[..]);
    let moved = (0..h * w)
        .filter(|&p| got.data()[p * 3..p * 3 + 3] != cur[p * 3..p * 3 + 3])
        .count();
    let kept = (0..h * w)
        .filter(|&p| got.data()[p * 3..p * 3 + 3] == cur[p * 3..p * 3 + 3])
        .count();
    assert!(
        moved > h * w / 3 && kept > h * w / 10,
        "both cases occur: {moved} moved, {kept} kept"
    );
}

/// `T` frames of a random pattern translating by `(sx, sy)` whole pixels per frame
/// (`I_t(x, y) = P(x - t sx, y - t sy)`), and its exact forward flow: `(sx, sy)`,
/// valid where `p + s` is inside the image.
fn translating(
    t_count: usize,
    h: usize,
    w: usize,
    sx: i64,
    sy: i64,
) -> (Vec<Tensor<f32>>, Vec<Tensor<f32>>) {
    let frames = (0..t_count as i64)
        .map(|t| {
            let data = (0..h * w * 3)
                .map(|i| {
                    let (p, c) = ((i / 3) as i64, (i % 3) as i64);
                    hash01(p % w as i64 - t * sx, p / w as i64 - t * sy, c)
                })
                .collect();
            Tensor::from_vec(data, &[h, w, 3])
        })
        .collect();
    let flow: Vec<f32> = (0..h * w)
        .flat_map(|p| {
            let (x, y) = ((p % w) as i64 + sx, (p / w) as i64 + sy);
            let inside = x >= 0 && y >= 0 && x < w as i64 && y < h as i64;
            [sx as f32, sy as f32, if inside { 1.0 } else { 0.0 }]
        })
        .collect();
    let flows = vec![Tensor::from_vec(flow, &[h, w, 3]); t_count - 1];
    (frames, flows)
}

#[test]
fn an_exact_integer_shift_gives_zero_error_and_wrong_flows_do_not() {
    let lpips = Lpips::load_default(Net::Alex).expect("weights");
    let (h, w) = (40, 48);
    let (frames, flows) = translating(4, h, w, 3, -2);
    let m = temporal_metrics(&frames, &flows, Some(&lpips)).expect("metrics");
    assert_eq!(m.per_step.len(), 3);
    assert_eq!(m.warp_error, 0.0);
    assert_eq!(m.w_lpips, Some(0.0));
    assert!((m.w_ssim - 1.0).abs() < 1e-12, "{}", m.w_ssim);
    // The disoccluded border (content entering at the right and top of frame t + 1)
    // exists and differs, so a zero result is not a trivial one.
    assert!(frames[1].data() != frames[0].data());
    // Negative controls: no flow, the opposite flow, and an off-by-one flow.
    for (name, fx, fy) in [
        ("zero", 0.0, 0.0),
        ("opposite", -3.0, 2.0),
        ("off by one", 2.0, -2.0),
    ] {
        let wrong: Vec<Tensor<f32>> = flows
            .iter()
            .map(|f| {
                let mut f = f.clone();
                for px in f.data_mut().chunks_exact_mut(3) {
                    px[0] = fx;
                    px[1] = fy;
                    px[2] = 1.0;
                }
                f
            })
            .collect();
        let bad = temporal_metrics(&frames, &wrong, Some(&lpips)).expect("metrics");
        assert!(bad.warp_error > 0.1, "{name}: {}", bad.warp_error);
        assert!(
            bad.w_ssim < 0.5 && bad.w_lpips.expect("lpips") > 0.01,
            "{name}: {bad:?}"
        );
    }
}

#[test]
fn sums_warp_errors_and_averages_ssim_and_lpips_over_steps() {
    let (h, w) = (32, 32);
    let frame = |v: f32| Tensor::<f32>::full(&[h, w, 3], v);
    let mut textured = frame(0.0);
    for (i, v) in textured.data_mut().iter_mut().enumerate() {
        *v = hash01(i as i64, 9, 0);
    }
    let frames = vec![frame(0.2), frame(0.5), textured.clone(), frame(0.6)];
    let still = Tensor::<f32>::from_vec(
        (0..h * w).flat_map(|_| [0.0, 0.0, 1.0]).collect(),
        &[h, w, 3],
    );
    let flows = vec![still; 3];
    let lpips = Lpips::load_default(Net::Alex).expect("weights");
    let m = temporal_metrics(&frames, &flows, Some(&lpips)).expect("metrics");
    // Zero flow: the warped frame is frame t + 1 itself.
    let want: Vec<f64> = (0..3)
        .map(|t| warp_error(&frames[t], &frames[t + 1]).expect("e"))
        .collect();
    // E_warp sums over the 3 channels: 3 * 0.3^2 for the first step.
    assert!((want[0] - 3.0 * 0.09).abs() < 1e-6, "{}", want[0]);
    assert!((m.warp_error - want.iter().sum::<f64>()).abs() < 1e-12);
    let ssims: Vec<f64> = (0..3)
        .map(|t| ssim(&frames[t + 1], &frames[t]).expect("s"))
        .collect();
    assert!((m.w_ssim - ssims.iter().sum::<f64>() / 3.0).abs() < 1e-12);
    let lp: Vec<f64> = (0..3)
        .map(|t| lpips.distance(&frames[t + 1], &frames[t]).expect("l"))
        .collect();
    assert!((m.w_lpips.expect("lpips") - lp.iter().sum::<f64>() / 3.0).abs() < 1e-9);
    for (s, (&e, &l)) in m.per_step.iter().zip(want.iter().zip(&lp)) {
        assert!((s.warp_error - e).abs() < 1e-12 && (s.lpips.expect("l") - l).abs() < 1e-9);
    }
    assert_eq!(
        temporal_metrics(&frames, &flows, None).expect("m").w_lpips,
        None
    );
}

/// The generator's exact flow must align consecutive frames of its own video: the
/// flow direction and the pixel-centre convention of the warp agree with
/// `forward_flow`. The reversed flow and the flow off by one pixel each way do worse.
/// (Not zero: the warp moves whole pixels, so a sub-pixel residual of the motion and
/// partly covered edge pixels remain.)
#[test]
fn the_generator_flow_aligns_its_own_video_frames() {
    let scene = build_scene("dolly").expect("scene");
    let cam = camera_at(video_position(), 64).expect("camera");
    let rgb = |t: f64| {
        let mut img = render_rgba(&scene, &cam, t, 2, 7);
        premultiply(&mut img.data);
        Tensor::from_vec(composite_premultiplied(&img.data, WHITE), &[64, 64, 3])
    };
    let (t0, t1) = (0.7, 0.8);
    let (f0, f1) = (rgb(t0), rgb(t1));
    let flow = forward_flow(&scene, &cam, t0, t1).to_tensor();
    let moving = flow
        .data()
        .chunks_exact(3)
        .filter(|v| v[0].abs() + v[1].abs() > 1.0)
        .count();
    assert!(
        moving > 100,
        "the scene must move between the frames ({moving} pixels)"
    );
    let error_with = |scale: f32, ox: f32, oy: f32| {
        let mut f = flow.clone();
        for v in f.data_mut().chunks_exact_mut(3) {
            v[0] = scale * v[0] + ox;
            v[1] = scale * v[1] + oy;
        }
        warp_error(&f0, &warp_forward(&f1, &f0, &f).expect("warp")).expect("error")
    };
    let exact = error_with(1.0, 0.0, 0.0);
    let none = warp_error(&f0, &f1).expect("error");
    eprintln!("E_warp {t0} -> {t1}: exact flow {exact:.5}, no flow {none:.5}");
    assert!(exact < 0.5 * none, "exact {exact} vs none {none}");
    for (name, s, ox, oy) in [
        ("reversed", -1.0, 0.0, 0.0),
        ("+x", 1.0, 1.0, 0.0),
        ("-x", 1.0, -1.0, 0.0),
        ("+y", 1.0, 0.0, 1.0),
        ("-y", 1.0, 0.0, -1.0),
    ] {
        let e = error_with(s, ox, oy);
        eprintln!("  {name}: {e:.5}");
        assert!(exact < 0.8 * e, "{name}: exact {exact} vs {e}");
    }
}

#[test]
fn bad_input_is_an_error_naming_what_is_wrong() {
    let (frames, flows) = translating(3, 16, 16, 1, 0);
    let err = temporal_metrics(&frames, &flows[..1], None).expect_err("count");
    assert!(
        matches!(
            err,
            TemporalError::Count {
                frames: 3,
                flows: 1
            }
        ),
        "{err}"
    );
    assert!(temporal_metrics(&frames[..1], &[], None).is_err());
    let mut bad = flows.clone();
    bad[1] = Tensor::zeros(&[16, 15, 3]);
    let err = temporal_metrics(&frames, &bad, None).expect_err("flow shape");
    assert!(
        matches!(err, TemporalError::FlowShape { index: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("flow 1"), "{err}");
    let mut other = frames.clone();
    other[2] = Tensor::zeros(&[16, 17, 3]);
    assert!(matches!(
        temporal_metrics(&other, &flows, None),
        Err(TemporalError::Metric(_))
    ));
}
