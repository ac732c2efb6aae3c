//! A wall-clock budget on a generated scene: the warm-up's plan is recorded in
//! `RUN/budget.json`, the run trains the scaled schedule it chose with the iteration
//! count its tail control set (recorded without the budget, so a resume keeps it),
//! and the run ends in the neighbourhood of its budget. The figure itself (how near, on real scenes) is a benchmark
//! (docs/results/budget.md); the bound here is loose, for a loaded test machine.

use std::time::Instant;

use maaf_io::TempDir;
use maaf_scene::TrainConfig;
use maaf_train::budget::BudgetPlan;
use maaf_train::data::synthetic::{GenerateOptions, generate};
use maaf_train::data::{Dataset, DatasetOptions};
use maaf_train::trainer::{BUDGET_FILE, train_run};

#[test]
fn a_budgeted_run_records_its_plan_and_ends_near_its_budget() {
    let t = TempDir::new("budget").expect("temp dir");
    let root = t.path().join("scene");
    let opts = GenerateOptions {
        seed: 2,
        ..GenerateOptions::small(64, 6)
    };
    generate(&root, &opts, &mut |_, _| {}).expect("generates");
    let data = Dataset::open(&root, DatasetOptions::default()).expect("opens");
    let mut config = TrainConfig {
        train_scale: 1.0,
        init_points: 500,
        budget: Some("8s".parse().expect("budget")),
        ..TrainConfig::default()
    };
    config.densify.max_gaussians = 4000;
    let run = t.path().join("run");
    let start = Instant::now();
    let summary = train_run(&data, config.clone(), &run, false).expect("trains");
    let wall = start.elapsed().as_secs_f64();

    let plan: BudgetPlan =
        serde_json::from_slice(&std::fs::read(run.join(BUDGET_FILE)).expect("the plan"))
            .expect("parses");
    assert_eq!(plan.budget_seconds, 8.0);
    // Densification ends inside the run, so the tail control set the final count.
    let iterations = plan.adjusted_iterations.expect("the tail was set");
    assert_eq!(summary.iterations, iterations);
    let recorded: TrainConfig =
        serde_json::from_slice(&std::fs::read(run.join("config.json")).expect("config"))
            .expect("parses");
    // The trainer fills in SaRO's `duration` from the data; the rest is the plan's.
    let mut expected = config.scaled_schedule(plan.scale);
    assert_eq!(expected.iterations, plan.iterations);
    expected.iterations = iterations;
    let warm_up = |c: &mut TrainConfig| *c.model.warm_up_mut().expect("saro");
    assert_eq!(warm_up(&mut recorded.clone()), warm_up(&mut expected));
    expected.model = recorded.model.clone();
    assert_eq!(recorded, expected);
    assert_eq!(recorded.budget, None);
    let [(n0, s0), (n1, s1)] = plan.step_seconds;
    assert!(n1 > n0 && s0 > 0.0 && s1 > 0.0, "{plan:?}");
    assert!(
        plan.predicted_seconds <= 8.0 && plan.predicted_seconds > 4.0,
        "{plan:?}"
    );
    assert!(wall < 3.0 * 8.0, "an 8 s budget took {wall:.1} s: {plan:?}");

    // A resume keeps the chosen schedule: no second plan.
    let planned = std::fs::read(run.join(BUDGET_FILE)).expect("plan");
    let again = train_run(&data, recorded.clone(), &run, true).expect("resumes");
    assert_eq!(again.iterations, iterations);
    assert_eq!(std::fs::read(run.join(BUDGET_FILE)).expect("plan"), planned);
}
