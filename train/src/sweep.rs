//! Ablation sweeps as plain job lists: a small grid of config values
//! becomes one run folder per point, each with its resolved `config.json`, and one shell
//! line per point that trains and evaluates it. The lines are independent, so
//! `bash jobs.txt` runs them one after another, `parallel -j2 < jobs.txt` (GNU
//! parallel) two at a time, and a cluster's array job runs line `$TASK_ID`; maaf has no
//! scheduler of its own.
//!
//! An axis is `dotted.key=v1,v2,...` over the JSON form of [`TrainConfig`], e.g.
//! `filter.grid_t=25,50,100,150` (the paper's T), `filter.refresh.every=100,200,300`,
//! `filter.h_x=0.1,0.2,0.3`, `filter.h_t=0.05,0.1,0.2`, `filter.weibull_lambda=0.5,1,2`.
//! Two layouts: [`Layout::OneAtATime`] (the ablation tables' layout: the base point plus
//! each axis varied alone) and [`Layout::Cross`] (every combination).

use serde_json::Value;

use crate::Error;
use maaf_scene::TrainConfig;

/// One axis of a sweep: a config key and the values it takes.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// Dotted path into the JSON form of [`TrainConfig`] (`filter.h_x`).
    pub key: String,
    /// The values, as JSON (numbers, booleans or strings).
    pub values: Vec<Value>,
}

impl Axis {
    /// Parses `key=v1,v2,...`. Each value is read as JSON when it parses (`25`, `0.1`,
    /// `true`), else as a string (`motion`).
    pub fn parse(text: &str) -> Result<Axis, Error> {
        let bad = |why: &str| Error::Input(format!("--grid {text:?}: {why}"));
        let (key, values) = text
            .split_once('=')
            .ok_or_else(|| bad("expected key=v1,v2,..."))?;
        let key = key.trim();
        if key.is_empty() || key.split('.').any(str::is_empty) {
            return Err(bad(
                "the key must be a dotted config path such as filter.h_x",
            ));
        }
        let values: Vec<Value> = values
            .split(',')
            .map(str::trim)
            .filter(|v| !v.is_empty())
            .map(|v| serde_json::from_str(v).unwrap_or_else(|_| Value::String(v.to_string())))
            .collect();
        if values.is_empty() {
            return Err(bad("no values"));
        }
        Ok(Axis {
            key: key.to_string(),
            values,
        })
    }
}

/// How the axes combine into points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// The base point, then every value of each axis with the other axes at the base
    /// (a value that leaves the config at the base is not repeated): `1 + sum (|axis| - repeats)` runs.
    OneAtATime,
    /// Every combination of the axes' values: `prod |axis|` runs.
    Cross,
}

/// One point of a sweep: its folder name, the overrides that define it and the
/// resolved, validated config.
#[derive(Clone, Debug)]
pub struct Point {
    /// Folder name: `base`, or the overrides as `key=value` joined by `,`.
    pub name: String,
    /// `(key, value)` overrides applied to the base config.
    pub overrides: Vec<(String, Value)>,
    /// The base config with the overrides, validated.
    pub config: TrainConfig,
}

/// Sets `key` (dotted) in the JSON form of a config. Fails, naming the key, when a
/// part of the path is not an existing field (so a typo never creates a new field).
fn set_key(root: &mut Value, key: &str, value: Value) -> Result<(), Error> {
    let mut node = root;
    for part in key.split('.') {
        node = node
            .as_object_mut()
            .and_then(|map| map.get_mut(part))
            .ok_or_else(|| {
                Error::Input(format!(
                    "--grid: {key:?} is not a config key ({part:?} unknown)"
                ))
            })?;
    }
    *node = value;
    Ok(())
}

/// `base` with `overrides` applied through its JSON form, then validated; errors name
/// the key and value.
pub fn apply(base: &TrainConfig, overrides: &[(String, Value)]) -> Result<TrainConfig, Error> {
    let mut json = serde_json::to_value(base)
        .map_err(|e| Error::Input(format!("cannot serialise the base config: {e}")))?;
    for (key, value) in overrides {
        set_key(&mut json, key, value.clone())?;
    }
    let label = point_name(overrides);
    let config: TrainConfig = serde_json::from_value(json)
        .map_err(|e| Error::Input(format!("sweep point {label}: {e}")))?;
    config
        .validate()
        .map_err(|e| Error::Input(format!("sweep point {label}: {e}")))?;
    Ok(config)
}

/// `key=value,...` of a point (`base` when there is no override).
fn point_name(overrides: &[(String, Value)]) -> String {
    if overrides.is_empty() {
        return "base".into();
    }
    overrides
        .iter()
        .map(|(k, v)| match v {
            Value::String(s) => format!("{k}={s}"),
            other => format!("{k}={other}"),
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// The points of a sweep over `axes` around `base`, every one validated before any
/// is written (a bad value fails the whole sweep up front). Names are unique.
pub fn points(base: &TrainConfig, axes: &[Axis], layout: Layout) -> Result<Vec<Point>, Error> {
    let mut keys: Vec<&str> = axes.iter().map(|a| a.key.as_str()).collect();
    keys.sort_unstable();
    if let Some(w) = keys.windows(2).find(|w| w[0] == w[1]) {
        return Err(Error::Input(format!("--grid: {:?} given twice", w[0])));
    }
    let override_sets: Vec<Vec<(String, Value)>> = match layout {
        Layout::OneAtATime => {
            let single = axes.iter().flat_map(|axis| {
                axis.values
                    .iter()
                    .map(|v| vec![(axis.key.clone(), v.clone())])
            });
            std::iter::once(Vec::new()).chain(single).collect()
        }
        Layout::Cross => axes.iter().fold(vec![Vec::new()], |sets, axis| {
            sets.iter()
                .flat_map(|set| {
                    axis.values.iter().map(move |v| {
                        let mut s = set.clone();
                        s.push((axis.key.clone(), v.clone()));
                        s
                    })
                })
                .collect()
        }),
    };
    let mut out: Vec<Point> = Vec::with_capacity(override_sets.len());
    for overrides in override_sets {
        let config = apply(base, &overrides)?;
        // One axis at a time: a value that gives the base config is the base point
        // (settings are compared, so 0.3 matches the f32 0.3 of the base).
        if layout == Layout::OneAtATime && !overrides.is_empty() && config == *base {
            continue;
        }
        let name = point_name(&overrides);
        if out.iter().any(|p| p.name == name) {
            return Err(Error::Input(format!("--grid: point {name} appears twice")));
        }
        out.push(Point {
            name,
            overrides,
            config,
        });
    }
    Ok(out)
}

/// `s` quoted for a POSIX shell where it needs quoting (`shlex`). A NUL byte, which
/// no shell word can hold (and no path or argument does), is dropped.
pub fn shell_quote(s: &str) -> String {
    let s = s.replace('\0', "");
    shlex::try_quote(&s).map_or(s.clone(), |q| q.into_owned())
}

/// Splits extra command-line arguments given as one string (`--eval-args "--scales
/// 1,2 --no-images"`) as a POSIX shell would: quotes group words. `what` names the
/// option in the error for unbalanced quotes.
pub fn split_args(text: &str, what: &str) -> Result<Vec<String>, Error> {
    shlex::split(text).ok_or_else(|| {
        Error::Input(format!(
            "{what} `{text}`: unbalanced quotes; quote each argument as a shell would"
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes(texts: &[&str]) -> Vec<Axis> {
        texts
            .iter()
            .map(|t| Axis::parse(t).expect("axis"))
            .collect()
    }

    #[test]
    fn axis_values_parse_as_json_or_strings() {
        let a = Axis::parse("filter.kind=none,mip3d, motion").expect("axis");
        assert_eq!(a.key, "filter.kind");
        assert_eq!(
            a.values,
            vec![Value::from("none"), "mip3d".into(), "motion".into()]
        );
        let b = Axis::parse("filter.h_x=0.1,0.2").expect("axis");
        assert_eq!(b.values, vec![Value::from(0.1), Value::from(0.2)]);
        for bad in ["filter.h_x", "=1,2", "filter..h_x=1", "filter.h_x="] {
            let e = Axis::parse(bad).expect_err(bad).to_string();
            assert!(e.contains(bad), "{bad}: {e}");
        }
    }

    #[test]
    fn one_at_a_time_varies_each_axis_alone_and_skips_the_base_value() {
        let base = TrainConfig::default();
        assert_eq!(base.filter.grid_t, 100);
        let grid = axes(&["filter.grid_t=25,50,100,150", "filter.h_x=0.1,0.2,0.3"]);
        let pts = points(&base, &grid, Layout::OneAtATime).expect("points");
        // base + 3 of T (100 is the base) + 2 of h_x (0.3 is the base).
        assert_eq!(pts.len(), 6);
        assert_eq!(pts[0].name, "base");
        assert_eq!(pts[0].config, base);
        let t25 = pts
            .iter()
            .find(|p| p.name == "filter.grid_t=25")
            .expect("T=25");
        assert_eq!(t25.config.filter.grid_t, 25);
        assert_eq!(t25.config.filter.h_x, base.filter.h_x);
        let hx = pts
            .iter()
            .find(|p| p.name == "filter.h_x=0.1")
            .expect("h_x");
        assert!((hx.config.filter.h_x - 0.1).abs() < 1e-7);
        assert_eq!(hx.config.filter.grid_t, 100);
    }

    #[test]
    fn cross_takes_every_combination() {
        let grid = axes(&[
            "filter.refresh.every=100,200,300",
            "filter.kind=mip3d,motion",
        ]);
        let pts = points(&TrainConfig::default(), &grid, Layout::Cross).expect("points");
        assert_eq!(pts.len(), 6);
        let p = pts
            .iter()
            .find(|p| p.name == "filter.refresh.every=300,filter.kind=mip3d")
            .expect("point");
        assert_eq!(p.config.filter.refresh.every, 300);
        assert_eq!(p.config.filter.kind, maaf_filter::FilterKind::Mip3d);
    }

    #[test]
    fn unknown_keys_wrong_types_and_invalid_values_fail_up_front_naming_them() {
        let base = TrainConfig::default();
        let cases = [
            ("filter.grid_tt=25", "filter.grid_tt"),
            ("filter.h_x=fast", "filter.h_x=fast"),
            ("filter.grid_t=1", "grid_t"),
        ];
        for (text, named) in cases {
            let e = points(&base, &axes(&[text]), Layout::Cross)
                .expect_err(text)
                .to_string();
            assert!(e.contains(named), "{text}: {e}");
        }
        let e = points(
            &base,
            &axes(&["filter.h_x=0.1", "filter.h_x=0.2"]),
            Layout::Cross,
        )
        .expect_err("repeated key")
        .to_string();
        assert!(e.contains("twice"), "{e}");
    }

    #[test]
    fn quoted_words_split_back_into_the_same_words() {
        let words = [
            "runs/sweep/filter.h_x=0.1",
            "my runs",
            "it's",
            "",
            "$HOME",
            "a\"b",
        ];
        let line: Vec<String> = words.iter().map(|w| shell_quote(w)).collect();
        assert_eq!(
            split_args(&line.join(" "), "--eval-args").expect("splits"),
            words
        );
        assert_eq!(
            shell_quote("runs/sweep"),
            "runs/sweep",
            "plain words stay bare"
        );
        assert_eq!(
            split_args("--scales '0.5, 1' --no-images", "--eval-args").expect("splits"),
            ["--scales", "0.5, 1", "--no-images"]
        );
        let e = split_args("--scales '1", "--eval-args").expect_err("unbalanced");
        assert!(e.to_string().contains("unbalanced quotes"), "{e}");
    }
}
