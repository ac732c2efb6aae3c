//! What `filter.max_views` costs: the motion filter's nu(t) from every training view
//! a run observed against nu(t) from the even stride of them the cap keeps
//! ([`maaf_filter::observed_frames`]), on the run's own final observations.
//!
//! `cargo run --release -p maaf-train --example observation_cap -- RUN DATA CAP...`
//!
//! RUN is a motion-filter run trained with all views observed (views <= its
//! `max_views`), DATA its data set (only the training times are read). Prints, per
//! cap, the table's bytes per Gaussian, the refresh time, and the distribution of
//! `|nu_cap(t) - nu_all(t)| / nu_all(t)` over every Gaussian and time bin.

use std::path::{Path, PathBuf};
use std::time::Instant;

use maaf_filter::{CameraTime, MotionCurves, ObservationTable, observed_frames};
use maaf_scene::TrainConfig;
use maaf_train::data::{Dataset, DatasetOptions, Split};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [run, data, caps @ ..] = args.as_slice() else {
        return Err("usage: observation_cap RUN DATA CAP...".into());
    };
    let run = PathBuf::from(run);
    let config_path = run.join("config.json");
    let text = std::fs::read_to_string(&config_path)
        .map_err(|e| format!("{}: {e}", config_path.display()))?;
    let config: TrainConfig =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", config_path.display()))?;
    let data =
        Dataset::open(Path::new(data), DatasetOptions::default()).map_err(|e| e.to_string())?;
    let frames: Vec<CameraTime> = data
        .times(Split::Train)
        .iter()
        .enumerate()
        .map(|(camera, &t)| CameraTime {
            camera,
            time: t as f32,
        })
        .collect();
    let (rows, width, values) = observations(&run.join("model/tensors.safetensors"))?;
    if width != frames.len() {
        return Err(format!(
            "{}: {width} observed views, the data set has {} training views (a capped run?)",
            run.display(),
            frames.len()
        ));
    }
    let cfg = &config.filter;
    let table = |kept: &[usize]| {
        let times = kept.iter().map(|&f| frames[f].time).collect();
        let mut t = ObservationTable::new(times, rows);
        for n in 0..rows {
            let row = &values[n * width..(n + 1) * width];
            for (slot, &f) in t.row_mut(n).iter_mut().zip(kept) {
                *slot = row[f];
            }
        }
        t
    };
    let refresh = |t: &ObservationTable| {
        let start = Instant::now();
        let curves = MotionCurves::refresh(t, cfg).map_err(|e| e.to_string());
        (curves, start.elapsed().as_secs_f64())
    };
    let (all, all_s) = refresh(&table(&observed_frames(&frames, width)));
    let all = all?;
    println!(
        "{rows} Gaussians, {width} views: {} B per Gaussian, refresh {all_s:.2} s",
        4 * width
    );
    for cap in caps {
        let cap: usize = cap
            .parse()
            .map_err(|_| format!("cap `{cap}` is not a count"))?;
        let kept = observed_frames(&frames, cap);
        let (capped, s) = refresh(&table(&kept));
        let capped = capped?;
        let mut rel: Vec<f32> = (0..rows)
            .flat_map(|n| {
                let (a, b) = (all.curve(n), capped.curve(n));
                a.into_iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).abs() / x)
                    .collect::<Vec<_>>()
            })
            .collect();
        rel.sort_by(f32::total_cmp);
        let q = |p: f64| rel[((rel.len() - 1) as f64 * p) as usize];
        let mean = rel.iter().map(|&r| f64::from(r)).sum::<f64>() / rel.len() as f64;
        println!(
            "cap {cap}: {} views, {} B per Gaussian, refresh {s:.2} s; |dnu|/nu mean {:.4} median {:.4} p95 {:.4} p99 {:.4} max {:.4}",
            kept.len(),
            4 * kept.len(),
            mean,
            q(0.5),
            q(0.95),
            q(0.99),
            q(1.0)
        );
    }
    Ok(())
}

/// The `observations` tensor of a checkpoint: rows, width and values.
fn observations(path: &Path) -> Result<(usize, usize, Vec<f32>), String> {
    let blob = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let st = safetensors::SafeTensors::deserialize(&blob)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let t = st
        .tensor("observations")
        .map_err(|e| format!("{}: observations: {e}", path.display()))?;
    let [rows, width] = t.shape() else {
        return Err(format!("{}: observations are not [N, F]", path.display()));
    };
    let values = t
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok((*rows, *width, values))
}
