//! The cost of SaRO's default configuration at 20 000 Gaussians, printed rather than
//! asserted (run by hand, `--ignored`).

use super::*;

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
/// `cargo test -p maaf-models cost_report -- --ignored --nocapture`.
/// Prints thread CPU times (single-threaded code); never asserts a time (the
/// machine's speed drifts; docs/performance.md).
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
        randomise_planes(&mut model, -0.1, 0.1, 0);
        model.set_dynamic(true);
        let field = model.field.num_scalars();
        let mut mlps = vec![&model.ids.motion, &model.ids.rot, &model.ids.life];
        mlps.extend(model.ids.sh.as_ref());
        let mlp_scalars: usize = mlps.iter().map(|m| m.num_params(&model.params)).sum();
        let per_gaussian = (model.params.num_scalars() - field - mlp_scalars) / n;
        println!(
            "{label}: planes {field} scalars ({:.2} MB f32), MLPs {mlp_scalars} ({:.2} MB), \
             {per_gaussian} scalars per Gaussian ({:.2} MB at N = {n}); Adam triples all",
            field as f64 * 4e-6,
            mlp_scalars as f64 * 4e-6,
            (per_gaussian * n) as f64 * 4e-6
        );
        let reps = 3;
        let mut t = [0.0; 5];
        for _ in 0..reps {
            let tape = Tape::new();
            let t0 = clock();
            let planes = model
                .ids
                .planes
                .map(|id| tape.var(model.params.value(id).clone()));
            let sample = PlaneSample::new(&model.field, std::sync::Arc::new(model.field_query()));
            let f = tape.apply1(sample, &planes);
            let t1 = clock();
            tape.backward(f.sum()).expect("finite");
            let t2 = clock();
            let tape = Tape::new();
            let t3 = clock();
            let bound = bind_tape(&model, &tape);
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
