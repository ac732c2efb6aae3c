//! Checks of the tracking model: frame switches (constant velocity, neighbours,
//! optimiser restarts, training times), rendering at and between frame times, the
//! gradient of everything it outputs, its checkpoint buffers and row selection, and
//! the choice of initial points.

use maaf_autodiff::check::{GradcheckConfig, gradcheck};
use maaf_autodiff::{PerGaussian, Tape, Tensor};

use super::*;
use crate::params::BoundParams;
use crate::{ModelConfig, build_model, flatten_outputs};

/// Three frames at 0, 0.25 and 0.5 over 20 iterations: frame 0 takes 10, then 5 and 5.
fn init(n: usize) -> ModelInit {
    ModelInit {
        cloud: PointCloud::random_in_box(n, -1.0, 1.0, 7),
        extent: 2.0,
        seed: 0,
        times: vec![0.0, 0.25, 0.5],
        iterations: 20,
    }
}

fn config() -> TrackConfig {
    TrackConfig {
        first_frame_iterations: 0.5,
        knn: 4,
        neighbour_falloff: 1.0,
        sh_degree: 1,
        ..TrackConfig::default()
    }
}

fn shift(t: &Tensor<f64>, by: f64) -> Tensor<f64> {
    Tensor::from_vec(
        t.data()
            .iter()
            .enumerate()
            .map(|(k, v)| v + by * (0.3 + (k % 7) as f64 / 7.0))
            .collect(),
        t.shape(),
    )
}

/// A model moved through frames 0 and 1 into frame 2, each frame's centres and
/// quaternions changed before the next switch, and the colours changed in frame 2.
fn tracked() -> TrackModel<f64> {
    let mut m = TrackModel::<f64>::new(config(), &init(20)).expect("model");
    let (xyz, rot, rgb) = (m.ids.xyz, m.ids.rotation, m.ids.rgb);
    for it in [11, 16] {
        let p = &mut m.params;
        *p.value_mut(xyz) = shift(p.value(xyz), 0.1);
        *p.value_mut(rot) = shift(p.value(rot), 0.2);
        m.set_iteration(it);
    }
    *m.params.value_mut(rgb) = shift(m.params.value(rgb), 0.05);
    m
}

#[test]
fn a_switch_stores_the_frame_and_starts_the_next_at_constant_velocity() {
    let mut m = TrackModel::<f64>::new(config(), &init(20)).expect("model");
    let (xyz, rot) = (m.ids.xyz, m.ids.rotation);
    m.set_iteration(10);
    assert_eq!(m.current_frame(), 0);
    assert!(m.neighbours().is_none() && m.buffers().is_empty());
    let a = shift(m.params.value(xyz), 0.1);
    *m.params.value_mut(xyz) = a.clone();
    m.set_iteration(11);
    assert_eq!(m.current_frame(), 1);
    assert_eq!(m.finished[0].means, a);
    // Frame 1 starts where frame 0 ended (no velocity yet).
    assert_eq!(m.params.value(xyz), &a);
    let nb = m.neighbours().expect("found at the first switch");
    assert_eq!((nb.len(), nb.k), (20, 4));
    assert_eq!(
        m.previous_colour.as_deref(),
        Some(m.params.value(m.ids.rgb))
    );
    let c = shift(&a, 0.5);
    *m.params.value_mut(xyz) = c.clone();
    m.set_iteration(16);
    assert_eq!(m.current_frame(), 2);
    let guess = c.zip_map(&a, |c, a| c + (c - a));
    assert_eq!(m.params.value(xyz), &guess);
    let q = m.params.value(rot).data();
    for row in q.chunks_exact(4) {
        let n: f64 = row.iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-14, "unit quaternions");
    }
    // Moments restart at the first iteration of frames 1 and 2 only.
    let names = |it| m.reset_moments(it);
    assert_eq!(names(16), ["xyz", "rotation"]);
    assert!(names(17).is_empty() && names(1).is_empty());
    let t = m.training_time(17).expect("a time");
    assert_eq!((t.time, t.since), (0.5, 16));
    m.set_iteration(16);
    assert_eq!(m.current_frame(), 2, "no switch twice");
    // Opacity and scales are frozen after frame 0.
    let frozen = &m.params.param(m.ids.opacity).lr;
    assert_eq!((frozen.at(9), frozen.at(10)), (0.05, 0.0));
}

/// `deform(t)` of `m` bound on constants, as plain (means, quats).
fn at_time(m: &TrackModel<f64>, t: f64) -> (Tensor<f64>, Tensor<f64>) {
    let tape = Tape::new();
    let params = m.params.bind_constants(&tape);
    let g = m.bind_track(&params).deform(t);
    let out = (g.means.value().clone(), g.quats.value().clone());
    drop(params);
    out
}

#[test]
fn deform_gives_each_frame_at_its_time_and_interpolates_between() {
    let m = tracked();
    let (f0, f1) = (&m.finished[0], &m.finished[1]);
    let current = (
        m.params.value(m.ids.xyz).clone(),
        m.params.value(m.ids.rotation).clone(),
    );
    assert_eq!(at_time(&m, 0.0), (f0.means.clone(), f0.quats.clone()));
    assert_eq!(at_time(&m, -3.0), at_time(&m, 0.0), "clamped before");
    assert_eq!(at_time(&m, 0.25), (f1.means.clone(), f1.quats.clone()));
    assert_eq!(at_time(&m, 0.5), current);
    assert_eq!(at_time(&m, 0.9), current, "clamped after the current frame");
    let unit = frames::normalise_rows(&current.1);
    for (t, from, to) in [
        (0.0625, (&f0.means, &f0.quats), (&f1.means, &f1.quats)),
        (0.3125, (&f1.means, &f1.quats), (&current.0, &unit)),
    ] {
        let a = 0.25;
        let (means, quats) = at_time(&m, t);
        for k in 0..means.len() {
            let want = (1.0 - a) * from.0.data()[k] + a * to.0.data()[k];
            assert!((means.data()[k] - want).abs() < 1e-14);
        }
        for (i, q) in quats.data().chunks_exact(4).enumerate() {
            let (p, r) = (
                &from.1.data()[4 * i..4 * i + 4],
                &to.1.data()[4 * i..4 * i + 4],
            );
            let s = if p.iter().zip(r).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
                -1.0
            } else {
                1.0
            };
            for c in 0..4 {
                let want = (1.0 - a) * p[c] + a * s * r[c];
                assert!((q[c] - want).abs() < 1e-14, "row {i}");
            }
        }
    }
}

#[test]
fn nlerp_takes_the_shorter_arc() {
    let mut m = tracked();
    // Frame 1's first quaternion is frame 0's, negated: the same rotation.
    let q0: Vec<f64> = m.finished[0].quats.data()[..4].to_vec();
    let f1 = Arc::make_mut(&mut m.finished[1]);
    for (v, q) in f1.quats.data_mut()[..4].iter_mut().zip(&q0) {
        *v = -q;
    }
    let (_, quats) = at_time(&m, 0.125);
    for (got, want) in quats.data()[..4].iter().zip(&q0) {
        assert!((got - want).abs() < 1e-14, "halfway is the same rotation");
    }
}

/// Checks the gradient of every output of the tracked model (Gaussians at frame
/// times, between frames, clamped, and the four regularisers) with the ops' faults.
fn gradcheck_bound(faults: [bool; 3]) -> bool {
    let m = tracked();
    let store = m.params.clone();
    let times = [-1.0, 0.0, 0.1, 0.25, 0.4, 0.5, 0.7];
    let report = gradcheck(
        |_, vars| {
            let params = BoundParams::from_vars(&store, vars);
            let mut bound = m.bind_track(&params);
            bound.faults = faults;
            flatten_outputs(&bound, &times)
        },
        &store.tensors(),
        &GradcheckConfig::default(),
    );
    if !report.passed() && faults == [false; 3] {
        println!("{report}");
    }
    report.passed()
}

#[test]
fn every_output_has_the_gradient_of_finite_differences() {
    let m = tracked();
    let tape = Tape::new();
    let params = m.params.bind_constants(&tape);
    let terms = m.bind_track(&params).regularisers();
    let names: Vec<&str> = terms.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, [COLOUR, RIGIDITY, ROTATION, ISOMETRY]);
    assert!(
        terms.iter().all(|(_, v)| v.value().item() > 1e-4),
        "every term is live"
    );
    drop(params);
    assert!(gradcheck_bound([false; 3]));
    for k in 0..3 {
        let mut faults = [false; 3];
        faults[k] = true;
        assert!(!gradcheck_bound(faults), "fault {k} passed");
    }
}

#[test]
fn buffers_restore_the_frames_and_refuse_another_run() {
    let m = tracked();
    let buffers = m.buffers();
    let names: Vec<&str> = buffers.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, frames::BUFFERS);
    assert_eq!(buffers[0].1.shape(), [2, 20, 3]);
    let mut back = TrackModel::<f64>::new(config(), &init(20)).expect("model");
    back.params = m.params.clone();
    // As a checkpoint is read: the buffers, the iteration, the buffers again.
    for (name, value) in &buffers {
        back.load_buffer(name, value.clone()).expect("loads");
    }
    back.set_iteration(18);
    for (name, value) in &buffers {
        back.load_buffer(name, value.clone()).expect("loads again");
    }
    assert_eq!(back.finished, m.finished);
    assert_eq!(back.neighbours, m.neighbours);
    assert_eq!(back.previous_colour, m.previous_colour);
    assert_eq!(back.state_scalars(), 2 * 20 * 7);
    for t in [0.0, 0.1, 0.3, 0.5] {
        assert_eq!(at_time(&back, t), at_time(&m, t));
    }
    let mut other = init(20);
    other.times = vec![0.0, 0.3, 0.5];
    let mut wrong = TrackModel::<f64>::new(config(), &other).expect("model");
    let mut last = Ok(());
    for (name, value) in &buffers {
        last = wrong.load_buffer(name, value.clone());
    }
    let msg = last.expect_err("other times");
    assert!(
        msg.contains("not the first of this run's 3 frames"),
        "{msg}"
    );
    let msg = back
        .load_buffer("frame_means", Tensor::zeros(&[2, 20, 4]))
        .and_then(|()| back.load_buffer("frame_quats", buffers[1].1.clone()))
        .and_then(|()| back.load_buffer("frame_times", buffers[2].1.clone()))
        .and_then(|()| back.load_buffer("previous_colour", buffers[3].1.clone()))
        .expect_err("bad shape");
    assert!(
        msg.contains("buffer `frame_means` has shape [2, 20, 4]"),
        "{msg}"
    );
    assert!(back.load_buffer("velocity", Tensor::zeros(&[1])).is_err());
}

#[test]
fn a_row_selection_resizes_the_frames_and_finds_the_neighbours_again() {
    let mut m = tracked();
    let index: Vec<usize> = (0..20).filter(|i| i % 3 != 0).chain([1, 1]).collect();
    let before = m.finished[1].means.gather_rows(&index);
    (&mut m as &mut dyn Representation<f64>).select_rows(&index);
    assert_eq!(m.finished[1].means, before);
    assert_eq!(
        m.previous_colour.as_ref().map(|c| c.rows()),
        Some(index.len())
    );
    assert_eq!(m.neighbours().map(Neighbours::len), Some(index.len()));
    assert_eq!(m.params.value(m.ids.xyz).rows(), index.len());
}

#[test]
fn the_first_frame_takes_its_own_points_and_the_untimed_ones() {
    let times = [0.0, 0.25, 0.5];
    let cloud = |t: Vec<f64>| PointCloud {
        points: (0..t.len()).map(|i| [i as f64, 0.0, 0.0]).collect(),
        colours: vec![[0.5; 3]; t.len()],
        times: Some(t),
    };
    // Two points at frame 0 (one a rounding away), one each at frames 1 and 2, two
    // static points at random times.
    let c = cloud(vec![0.0, 1e-6, 0.25, 0.5, 0.123, 0.777]);
    let kept = first_frame_points(&c, &times);
    assert_eq!(
        kept.points.iter().map(|p| p[0]).collect::<Vec<_>>(),
        [0.0, 1.0, 4.0, 5.0]
    );
    // No point at frame 0: those of the earliest frame that has some.
    let c = cloud(vec![0.5, 0.25, 0.7, 0.25]);
    let kept = first_frame_points(&c, &times);
    assert_eq!(
        kept.points.iter().map(|p| p[0]).collect::<Vec<_>>(),
        [1.0, 2.0, 3.0]
    );
    let untimed = PointCloud {
        times: None,
        ..c.clone()
    };
    assert_eq!(first_frame_points(&untimed, &times), untimed);
}

#[test]
fn a_config_names_the_kind_and_a_short_run_is_refused() {
    let c: ModelConfig = serde_json::from_str(r#"{"kind": "track", "knn": 8}"#).expect("track");
    assert!(matches!(&c, ModelConfig::Track(t) if t.knn == 8 && t.rigidity == 4.0));
    assert_eq!((c.kind(), c.sh_degree()), ("track", 0));
    let mut short = init(20);
    short.iterations = 2;
    let err = build_model(&c, &short).err().expect("refused");
    assert!(err.contains("model.first_frame_iterations"), "{err}");
    let model = build_model(&c, &init(20)).expect("builds");
    assert_eq!(model.name(), "track");
}
