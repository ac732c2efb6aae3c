use super::cost::cost_table;
use super::tables::lpips_net_note;
use super::*;
use crate::ScaleResult;
use crate::metrics::rings::RingErrors;

fn run(scene: &str, filter: &str) -> SuiteRun {
    SuiteRun {
        scene: scene.into(),
        split: "test".into(),
        preset: "dnerf".into(),
        filter: filter.into(),
        background: "black".into(),
        seed: None,
        dir: format!("{scene}/{filter}").into(),
    }
}

fn eval(psnr: f64, scales: &[f64]) -> EvalReport {
    let cells = scales
        .iter()
        .map(|&s| {
            let mut c = ScaleResult::new(s, (8, 8), psnr + s, 0.9);
            c.lpips = Some(0.1 * s);
            c
        })
        .collect();
    let mut r = crate::report::ReportRun::for_test("x", "saro", "motion", cells).eval;
    r.train_seconds = psnr;
    r
}

#[test]
fn methods_average_their_evaluated_scenes_and_list_the_rest() {
    let all = [0.25, 1.0, 2.0, 4.0];
    let runs = vec![
        (run("a", "motion"), Some(eval(30.0, &all))),
        (run("a", "none"), Some(eval(20.0, &all))),
        (run("b", "motion"), Some(eval(34.0, &all))),
        (run("b", "none"), None),
    ];
    let s = summarise(&runs);
    assert_eq!(s.methods.len(), 2);
    assert_eq!(s.missing, vec![PathBuf::from("b/none")]);
    let motion = s.methods[0].average.as_ref().expect("average");
    assert_eq!(motion.scenes, 2);
    let at4 = motion.scales.iter().find(|c| c.scale == 4.0).expect("4x");
    assert!((at4.psnr - 36.0).abs() < 1e-12);
    assert!((motion.train_seconds - 32.0).abs() < 1e-12);
    let none = s.methods[1].average.as_ref().expect("average");
    assert_eq!(none.scenes, 1);
    // Tab. 2's avg: the mean of 1x, 2x, 4x (32 + 34 + 36) / 3.
    let table = tab2_table(&s);
    assert!(
        table.contains("| dnerf / motion / black (maaf) | 2 | 33.00 | 34.00 | 36.00 | 34.33 |"),
        "{table}"
    );
    assert!(
        table.contains("37.10") && table.contains("36.61"),
        "{table}"
    );
    assert!(released_table(&s).contains("32.28"));
}

#[test]
fn a_scene_with_several_seeds_counts_once_and_its_spread_is_reported() {
    let seeded = |scene: &str, seed| SuiteRun {
        seed: Some(seed),
        dir: format!("{scene}/motion-seed{seed}").into(),
        ..run(scene, "motion")
    };
    let runs = vec![
        (seeded("a", 0), Some(eval(30.0, &[1.0, 4.0]))),
        (seeded("a", 1), Some(eval(32.0, &[1.0, 4.0]))),
        (seeded("a", 2), Some(eval(34.0, &[1.0, 4.0]))),
        (seeded("b", 0), Some(eval(40.0, &[1.0, 4.0]))),
    ];
    let s = summarise(&runs);
    let avg = s.methods[0].average.as_ref().expect("average");
    assert_eq!((avg.scenes, avg.runs), (2, 4));
    // At 1x a's seeds give 31, 33, 35 (mean 33) and b 41: the scenes' mean is 37,
    // where the runs' mean would be 35; likewise the time, (32 + 40) / 2.
    assert!((avg.scales[0].psnr - 37.0).abs() < 1e-12, "{avg:?}");
    assert!((avg.train_seconds - 36.0).abs() < 1e-12);
    let md = markdown(&s);
    // The sample standard deviation of 31, 33, 35 is 2; b has one seed, no row.
    assert!(
        md.contains("| dnerf / motion / black | a | 3 | 33.00 ± 2.00 | 36.00 ± 2.00 |"),
        "{md}"
    );
    assert!(!md.contains("| dnerf / motion / black | b | 1 |"), "{md}");
    assert!(md.contains("| a seed 1 |") && md.contains("**average (2 scenes, 4 runs)**"));
    // A suite without seeds has no such section and reads as before.
    let plain = markdown(&summarise(&[(
        run("a", "motion"),
        Some(eval(30.0, &[1.0])),
    )]));
    assert!(!plain.contains("## Seeds") && plain.contains("**average (1 scenes)**"));
    let json = serde_json::to_string(&run("a", "motion")).expect("json");
    assert!(!json.contains("seed"), "{json}");
}

#[test]
fn a_scale_missing_in_one_scene_is_left_out_of_the_average() {
    let runs = vec![
        (run("a", "motion"), Some(eval(30.0, &[1.0, 2.0, 4.0]))),
        (run("b", "motion"), Some(eval(30.0, &[1.0, 2.0]))),
    ];
    let s = summarise(&runs);
    let avg = s.methods[0].average.as_ref().expect("average");
    let scales: Vec<f64> = avg.scales.iter().map(|c| c.scale).collect();
    assert_eq!(scales, vec![1.0, 2.0]);
    let md = markdown(&s);
    assert!(md.contains("**average (2 scenes)**"), "{md}");
}

#[test]
fn the_cost_table_splits_training_time_by_phase_and_averages_the_shares() {
    let runs = vec![
        (run("a", "motion"), Some(eval(30.0, &[1.0]))),
        (run("b", "motion"), Some(eval(30.0, &[1.0]))),
        (run("c", "motion"), Some(eval(30.0, &[1.0]))),
    ];
    let mut s = summarise(&runs);
    let timings = |field_mlp, backward, cpu, machine_cpu| Timings {
        field_mlp,
        render_forward: 1.0,
        backward,
        optimiser: 1.0,
        statistics: 1.0,
        filter_refresh: 0.5,
        densification: 0.5,
        cpu,
        machine_cpu,
    };
    // a: 2 + 1 + 4 + 1 + 1 + 0.5 + 0.5 = 10 s; b: 6 + 1 + 2 + 1 + 1 + 0.5 + 0.5 = 12 s.
    // CPU: a 0.25 min, b 0.35 min; the phases' sum leaves CPU time out. Others
    // busy: a (20 - 15) / 10 = 0.50 cores; b predates the machine clock (blank).
    s.methods[0].scenes[0].phases = Some(timings(2.0, 4.0, 15.0, 20.0));
    s.methods[0].scenes[1].phases = Some(timings(6.0, 2.0, 21.0, 0.0));
    let a = phase_shares(s.methods[0].scenes[0].phases.as_ref()).expect("shares");
    assert!((a[0] - 20.0).abs() < 1e-9 && (a[2] - 40.0).abs() < 1e-9 && (a[4] - 10.0).abs() < 1e-9);
    assert!((a.iter().sum::<f64>() - 100.0).abs() < 1e-9);
    let table = cost_table(&s);
    assert!(
        table.contains("| 0.25 | 0.50 | 20 | 10 | 40 | 10 | 10 | 5 | 5 |"),
        "{table}"
    );
    assert!(
        table.contains("| 0.35 | - | 50 | 8 | 17 | 8 | 8 | 4 | 4 |"),
        "{table}"
    );
    // Scene c has no summary: dashes, and the average is over a and b only
    // (field + MLPs (20 + 50) / 2 = 35, filter (5 + 4.17) / 2 = 4.58; CPU
    // (0.25 + 0.35) / 2 = 0.30; others busy over a alone).
    assert!(
        table.contains("| - | - | - | - | - | - | - | - | - |"),
        "{table}"
    );
    assert!(
        table.contains("| 0.30 | 0.50 | 35 | 9 | 28 | 9 | 9 | 5 | 5 |"),
        "{table}"
    );
    assert_eq!(phase_shares(Some(&Timings::default())), None);
}

#[test]
fn lpips_is_averaged_only_over_one_backbone_and_the_note_says_which() {
    let vgg = |psnr| {
        let mut e = eval(psnr, &[1.0, 4.0]);
        e.lpips_net = "vgg".into();
        e
    };
    let all_vgg = summarise(&[
        (run("a", "motion"), Some(vgg(30.0))),
        (run("b", "motion"), Some(vgg(31.0))),
    ]);
    let avg = all_vgg.methods[0].average.as_ref().expect("average");
    assert_eq!(avg.lpips_net.as_deref(), Some("vgg"));
    assert!((avg.scales[1].lpips.expect("lpips") - 0.4).abs() < 1e-12);
    assert!(lpips_net_note(&all_vgg).contains("the LPIPS column compares"));

    let mixed = summarise(&[
        (run("a", "motion"), Some(vgg(30.0))),
        (run("b", "motion"), Some(eval(31.0, &[1.0, 4.0]))),
    ]);
    let avg = mixed.methods[0].average.as_ref().expect("average");
    assert_eq!(avg.lpips_net, None);
    assert!(avg.scales.iter().all(|c| c.lpips.is_none()), "{avg:?}");
    assert!(avg.scales.iter().all(|c| c.psnr > 0.0));
    let note = lpips_net_note(&mixed);
    assert!(note.contains("use mixed features"), "{note}");

    let alex = summarise(&[(run("a", "none"), Some(eval(30.0, &[4.0])))]);
    let note = lpips_net_note(&alex);
    assert!(note.contains("use AlexNet features") && note.contains("--lpips-net vgg"));
}

#[test]
fn paired_gains_use_only_shared_scenes_of_one_preset_and_background() {
    let all = [0.25, 1.0, 2.0, 4.0];
    let seeded = |seed| SuiteRun {
        seed: Some(seed),
        dir: format!("a/motion-seed{seed}").into(),
        ..run("a", "motion")
    };
    let white = SuiteRun {
        background: "white".into(),
        ..run("a", "motion")
    };
    let runs = vec![
        (run("a", "none"), Some(eval(30.0, &all))),
        // b's unfiltered run lacks 4x: no gain against none at 4x.
        (run("b", "none"), Some(eval(20.0, &[0.25, 1.0, 2.0]))),
        (run("a", "mip3d"), Some(eval(31.0, &all))),
        (seeded(0), Some(eval(32.0, &all))),
        (seeded(1), Some(eval(34.0, &all))),
        (run("b", "motion"), Some(eval(19.0, &all))),
        // c has no unfiltered run: it is in motion's average, not in its gain.
        (run("c", "motion"), Some(eval(50.0, &all))),
        (white, Some(eval(40.0, &all))),
    ];
    let s = summarise(&runs);
    let pairs: Vec<(&str, &str, usize)> = s
        .gains
        .iter()
        .map(|g| (g.method.as_str(), g.base.as_str(), g.scenes.len()))
        .collect();
    // The white run shares no preset and background with another method.
    assert_eq!(
        pairs,
        vec![
            ("dnerf / mip3d / black", "dnerf / none / black", 1),
            ("dnerf / motion / black", "dnerf / none / black", 2),
            ("dnerf / motion / black", "dnerf / mip3d / black", 1),
        ]
    );
    // motion against none: a's seeds average 33 (+3 over 30), b 19 (-1 under 20): the
    // mean +1, ahead on one of two; the plain averages would say 34 - 25 = +9.
    let g = &s.gains[1];
    let at1 = g.scales.iter().find(|c| c.scale == 1.0).expect("1x");
    assert!((at1.psnr - 1.0).abs() < 1e-12 && at1.ahead == 1, "{g:?}");
    assert!(g.scales.iter().all(|c| c.scale != 4.0), "{g:?}");
    assert!((s.gains[2].scales[0].psnr - 2.0).abs() < 1e-12);
    let md = markdown(&s);
    assert!(
        md.contains(
            "| dnerf / motion / black | dnerf / none / black | 2 | +1.00 (1/2) | +1.00 (1/2) | +1.00 (1/2) | - |"
        ),
        "{md}"
    );
    // The published gains: MAAF over SaRO-GS (Tab. 2), the release's at 4x only.
    assert!(
        md.contains("| SaRO-GS | 8 | - | +0.49 | +4.46 | +5.21 |"),
        "{md}"
    );
    assert!(
        md.contains("| SpeeDe3DGS | 8 | - | - | - | +4.45 |"),
        "{md}"
    );
    // One method alone: no pairs, no section.
    let alone = summarise(&[(run("a", "motion"), Some(eval(30.0, &all)))]);
    assert!(alone.gains.is_empty() && !markdown(&alone).contains("## Paired gains"));
}

#[test]
fn the_speed_chart_places_each_method_at_its_mean_time_and_psnr_beside_the_release() {
    let all = [1.0, 4.0];
    let runs = vec![
        (run("a", "motion"), Some(eval(30.0, &all))),
        (run("b", "motion"), Some(eval(36.0, &all))),
        (run("a", "none"), Some(eval(24.0, &[1.0]))),
    ];
    let s = summarise(&runs);
    // 1x: both methods (the release publishes 4x only).
    let at1 = chart::points(&s, 1.0);
    assert_eq!(at1.len(), 2, "{at1:?}");
    assert!((at1[0].minutes - 33.0 / 60.0).abs() < 1e-12 && (at1[0].psnr - 34.0).abs() < 1e-12);
    assert_eq!(at1[0].label, "dnerf / motion / black (2 scenes)");
    assert!((at1[1].minutes - 24.0 / 60.0).abs() < 1e-12 && (at1[1].psnr - 25.0).abs() < 1e-12);
    assert_ne!(at1[0].colour, at1[1].colour, "filters keep their colours");
    // 4x: motion only (none lacks 4x), then the released rows with their GPU minutes.
    let at4 = chart::points(&s, 4.0);
    assert!(!at4[0].published && (at4[0].psnr - 37.0).abs() < 1e-12);
    let maaf = at4
        .iter()
        .find(|p| p.published && (p.psnr - 32.28).abs() < 1e-9)
        .expect("the released MAAF row");
    assert!((maaf.minutes - 6.48).abs() < 1e-12, "{maaf:?}");
    assert_eq!(at4.iter().filter(|p| !p.published).count(), 1);
    // The figure is written as a PNG of the chart's size.
    let dir = std::env::temp_dir().join(format!("maaf_speed_chart_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("mkdir");
    let path = dir.join("speed_quality.png");
    chart::speed_quality(&s, &path).expect("chart");
    let img = image::open(&path).expect("png");
    assert_eq!((img.width(), img.height()), (1400, 620));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn evaluations_on_other_backgrounds_are_read_and_tabulated_beside_the_run_s_own() {
    let dir = std::env::temp_dir().join(format!("maaf_suite_other_bg_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scales = [0.25, 1.0];
    let mut runs = Vec::new();
    for (scene, others) in [("a", vec![([1.0f32; 3], 20.0)]), ("b", vec![])] {
        let mut r = run(scene, "motion");
        r.dir = dir.join(scene);
        std::fs::create_dir_all(&r.dir).expect("mkdir");
        let write = |name: &str, e: &EvalReport| {
            let text = serde_json::to_string(e).expect("json");
            std::fs::write(r.dir.join(name), text).expect("write");
        };
        write("eval.json", &eval(30.0, &scales));
        for (colour, psnr) in others {
            let mut e = eval(psnr, &scales);
            e.background = colour;
            e.trained_background = Some([0.0; 3]);
            write(&format!("{}.json", e.name()), &e);
        }
        runs.push(r);
    }
    let out = write_suite_report(&runs, &dir.join("report")).expect("report");
    let md = std::fs::read_to_string(&out.markdown).expect("report.md");
    assert!(md.contains("## PSNR on other backgrounds"), "{md}");
    // eval(p) puts p + scale at each scale: own 30.25 / 31.00, white 20.25 / 21.00.
    assert!(
        md.contains("| dnerf / motion / black | a | black (own) | 30.25 | 31.00 |"),
        "{md}"
    );
    assert!(
        md.contains("| dnerf / motion / black | a | white | 20.25 | 21.00 |"),
        "{md}"
    );
    assert!(
        !md.contains("| b | black (own)"),
        "a run without one has no row: {md}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out.json).expect("json")).expect("parse");
    let a = &json["methods"][0]["scenes"][0]["other_backgrounds"][0];
    assert_eq!(a["background"], "white");
    // Without any such file the section is left out.
    std::fs::remove_file(dir.join("a/eval-on-white.json")).expect("rm");
    let md = std::fs::read_to_string(
        write_suite_report(&runs, &dir.join("report"))
            .expect("report")
            .markdown,
    )
    .expect("report.md");
    assert!(!md.contains("other backgrounds"), "{md}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ring_shares_pool_the_shared_scenes_after_averaging_seeds_and_follow_the_paper_s_split() {
    let pixels = [10, 20, 30, 40, 100];
    let with_rings = |psnr: f64, sse: [f64; 5]| {
        let mut e = eval(psnr, &[0.25, 1.0]);
        e.scales[0].rings = Some(RingErrors { pixels, sse });
        e
    };
    let seeded = |seed| SuiteRun {
        seed: Some(seed),
        dir: format!("a/motion-seed{seed}").into(),
        ..run("a", "motion")
    };
    let mut runs = vec![
        (
            run("a", "none"),
            Some(with_rings(20.0, [4.0, 2.0, 1.0, 2.0, 0.5])),
        ),
        (
            run("b", "none"),
            Some(with_rings(20.0, [2.0, 1.0, 1.0, 1.0, 0.1])),
        ),
        (seeded(0), Some(with_rings(21.0, [1.0, 1.0, 1.0, 1.0, 0.5]))),
        (seeded(1), Some(with_rings(21.0, [3.0, 1.0, 1.0, 1.0, 0.5]))),
        (
            run("b", "motion"),
            Some(with_rings(21.0, [1.0, 1.0, 1.0, 3.0, 0.1])),
        ),
    ];
    let s = summarise(&runs);
    let g = &s.gains[0];
    assert_eq!(
        (g.method.as_str(), g.base.as_str()),
        ("dnerf / motion / black", "dnerf / none / black")
    );
    // Only 1/4x has rings. Pooled: none [6, 3, 2, 3, 0.6], motion (a's seeds
    // averaged to [2, 1, 1, 1, 0.5]) [3, 2, 2, 4, 0.6]: cut [3, 1, 0, -1, 0] of 3.
    assert_eq!(g.rings.len(), 1);
    let r = g.rings[0];
    assert_eq!(r.scale, 0.25);
    let want = [1.0, 1.0 / 3.0, 0.0, -1.0 / 3.0, 0.0];
    for (got, want) in r.shares.iter().zip(want) {
        assert!((got - want).abs() < 1e-12, "{:?}", r.shares);
    }
    assert_eq!(r.pixels, [0.05, 0.1, 0.15, 0.2, 0.5]);
    assert!((r.removed - 3.0 / 14.6).abs() < 1e-12);
    let md = markdown(&s);
    for row in [
        "| silhouette ring (object, d = 1 px) | 100.0 (5.0) |",
        "| background halo (d <= 2 px) | -33.3 (20.0) |",
        "| squared error removed, % of the base's | 20.5 |",
        "| silhouette ring (object, d = 1 px) | 50.7 | 57.8 |",
    ] {
        assert!(md.contains(row), "`{row}` not in:\n{md}");
    }
    // A run without rings (data without alpha) takes the pair's rings away.
    runs[4].1.as_mut().expect("eval").scales[0].rings = None;
    let s = summarise(&runs);
    assert!(s.gains[0].rings.is_empty());
    assert!(!markdown(&s).contains("Where the gains lie"));
}

#[test]
fn each_method_s_scenes_are_placed_against_the_eight_in_the_paper_s_table() {
    let at = [1.0];
    let runs = vec![
        (run("mutant", "motion"), Some(eval(30.0, &at))),
        (run("standup", "motion"), Some(eval(30.0, &at))),
        (run("lego", "none"), Some(eval(20.0, &at))),
        (run("mutant", "none"), None),
    ];
    let s = summarise(&runs);
    // The not-yet-evaluated mutant run leaves `none` with lego alone.
    let sets: Vec<String> = s
        .scene_sets
        .iter()
        .map(|x| format!("{}: {}", x.method, x.scenes.join(", ")))
        .collect();
    assert_eq!(
        sets,
        [
            "dnerf / motion / black: mutant, standup",
            "dnerf / none / black: lego"
        ]
    );
    let md = markdown(&s);
    for row in [
        // (36.75 + 38.37) / 2 = 37.56, 2.54 above the eight's 35.02; lego 10.36 below.
        "| dnerf / motion / black | mutant, standup | 37.56 (+2.54) |",
        "| dnerf / none / black | lego | 24.66 (-10.36) |",
        "## How hard these scenes are",
    ] {
        assert!(md.contains(row), "`{row}` not in:\n{md}");
    }
    let json = serde_json::to_string(&s).expect("serialises");
    assert!(json.contains("\"scene_sets\"") && json.contains("tab:supp_zoomout"));
}
