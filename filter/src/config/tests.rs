//! Tests of the filter configuration: the defaults (the paper's values), every
//! refused value named by its field, custom kinds and estimators, JSON parsing, the
//! refresh schedule and the time bins.

use super::*;

#[test]
fn defaults_are_valid_and_paper_values() {
    let cfg = FilterConfig::default();
    cfg.validate().expect("defaults valid");
    assert_eq!(
        (cfg.h_x, cfg.h_t, cfg.grid_t, cfg.weibull_k),
        (0.3, 0.05, 100, 10.0)
    );
}

#[test]
fn bad_values_are_rejected_naming_the_field() {
    type Edit = Box<dyn Fn(&mut FilterConfig)>;
    let cases: Vec<(&str, Edit)> = vec![
        ("h_x", Box::new(|c| c.h_x = 0.0)),
        ("h_x", Box::new(|c| c.h_x = -0.3)),
        ("h_t", Box::new(|c| c.h_t = 0.0)),
        ("h_t", Box::new(|c| c.h_t = f32::NAN)),
        ("weibull_k", Box::new(|c| c.weibull_k = 0.0)),
        ("weibull_k", Box::new(|c| c.weibull_k = -2.0)),
        ("weibull_k", Box::new(|c| c.weibull_k = f32::INFINITY)),
        ("weibull_lambda", Box::new(|c| c.weibull_lambda = 0.0)),
        ("grid_x", Box::new(|c| c.grid_x = 1)),
        ("grid_x", Box::new(|c| c.grid_x = 256)),
        ("grid_t", Box::new(|c| c.grid_t = 1)),
        ("max_views", Box::new(|c| c.max_views = 0)),
        ("s3d", Box::new(|c| c.s3d = f32::NAN)),
        ("near", Box::new(|c| c.near = -1.0)),
        ("margin", Box::new(|c| c.margin = f32::INFINITY)),
        ("time_range", Box::new(|c| c.time_range = [1.0, 1.0])),
        ("time_range", Box::new(|c| c.time_range = [0.0, f32::NAN])),
        ("time_support", Box::new(|c| c.time_support = 0.0)),
        ("weibull_cutoff", Box::new(|c| c.weibull_cutoff = 1.0)),
        ("refresh.every", Box::new(|c| c.refresh.every = 0)),
    ];
    for (field, edit) in cases {
        let mut cfg = FilterConfig::default();
        edit(&mut cfg);
        let err = cfg.validate().expect_err(field).to_string();
        assert!(err.contains(&format!("`{field}`")), "{field}: {err}");
    }
}

#[test]
fn a_custom_kind_is_a_name_and_window_max_is_the_estimators() {
    let cfg = FilterConfig::from_json_str(r#"{"kind": "median"}"#).expect("custom");
    assert_eq!((cfg.kind.name(), cfg.filter_name()), ("median", "median"));
    for bad in [r#"{"kind": "window_max"}"#, r#"{"kind": "a b"}"#] {
        let err = FilterConfig::from_json_str(bad).expect_err(bad).to_string();
        assert!(err.contains("field `kind`"), "{err}");
    }
}

#[test]
fn json_parse_validates_and_names_unknown_fields() {
    let cfg = FilterConfig::from_json_str(r#"{"kind":"mip3d","h_x":0.2}"#).expect("parses");
    assert_eq!(
        (cfg.kind, cfg.h_x, cfg.grid_t),
        (FilterKind::Mip3d, 0.2, 100)
    );
    let err = FilterConfig::from_json_str(r#"{"h_t":-1}"#).expect_err("bad");
    assert!(err.to_string().contains("`h_t`"), "{err}");
    let err = FilterConfig::from_json_str(r#"{"hx":0.2}"#).expect_err("unknown");
    assert!(err.to_string().contains("hx"), "{err}");
}

#[test]
fn schedule_matches_mip_splatting() {
    let s = RefreshSchedule::default();
    let due: Vec<u64> = (1..=1000).filter(|&i| s.due(i, 1000, false)).collect();
    assert_eq!(due, vec![600, 700, 800, 900]);
    assert!(s.due(650, 1000, true));
    assert!(!s.due(1000, 1000, true), "never at the last iteration");
    let s = RefreshSchedule {
        after_densify: false,
        ..RefreshSchedule::default()
    };
    assert!(!s.due(650, 1000, true));
}
