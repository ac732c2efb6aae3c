//! `maaf export-ply`: a trained dynamic run as standard 3DGS PLY frames.
//!
//! A frame at time `t` is what the renderer draws at `t`
//! ([`crate::forward::gaussians_at`]: deformed, with the 3D filter folded into scale
//! and opacity as Mip-Splatting's fused export does, `s' = sqrt(s^2 + var)`,
//! `o' = o sqrt(prod s^2 / prod(s^2 + var))`), stored in the Inria parameterisation
//! (`log s'`, `logit o'`, SH up to the degree the run renders with), so that any 3DGS
//! viewer shows the frame as `maaf render` does. A sequence is a folder of
//! `frame_NNNN.ply` plus `frames.json` (file name and time of each frame), swapped
//! into place whole.

use std::path::{Path, PathBuf};

use maaf_autodiff::Tensor;
use maaf_autodiff::scalar::logit;
use maaf_splat::Gaussians;
use maaf_splat::sh::num_coeffs;
use serde_json::json;

use crate::trainer::Trainer;
use crate::{Error, write_atomic};

/// The deformed, filtered Gaussians of `trainer` at `time` as a static 3DGS scene, SH
/// truncated to the degree the run renders with ([`Trainer::render_settings`]).
pub fn frame_gaussians(trainer: &Trainer, time: f64) -> Gaussians {
    let [means, scales, quats, opacity, sh] = trainer.frame_at(time);
    let n = means.shape()[0];
    let stored = sh.shape()[1];
    let degree = trainer.render_settings(trainer.iteration).sh_degree;
    let degree = (0..=degree)
        .rev()
        .find(|&d| num_coeffs(d) <= stored)
        .unwrap_or(0);
    let k = num_coeffs(degree);
    let sh_data: Vec<f32> = (0..n)
        .flat_map(|i| {
            sh.data()[i * stored * 3..(i * stored + k) * 3]
                .iter()
                .copied()
        })
        .collect();
    Gaussians {
        means,
        log_scales: scales.map(f32::ln),
        quats,
        raw_opacity: opacity.map(logit),
        sh: Tensor::from_vec(sh_data, &[n, k, 3]),
        sh_degree: degree,
    }
}

/// Writes the frame at `time` to `out` as a binary 3DGS PLY (atomically).
pub fn export_frame(trainer: &Trainer, time: f64, out: &Path) -> Result<(), Error> {
    maaf_splat::write_ply(out, &frame_gaussians(trainer, time))
        .map_err(|e| Error::Input(e.to_string()))
}

/// Writes `frames` evenly spaced times over `[t0, t1]` into the folder `out` as
/// `frame_0000.ply ...` and `frames.json` (`{"frames": [{"file", "time"}]}`), built in
/// a temporary sibling and swapped in whole. Returns the PLY paths.
pub fn export_sequence(
    trainer: &Trainer,
    (t0, t1): (f64, f64),
    frames: usize,
    out: &Path,
) -> Result<Vec<PathBuf>, Error> {
    if frames == 0 {
        return Err(Error::Input("--frames must be at least 1".into()));
    }
    let tmp = maaf_io::temp_sibling(out);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    }
    std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let result = (|| {
        let mut index = Vec::with_capacity(frames);
        for i in 0..frames {
            let t = if frames == 1 {
                t0
            } else {
                t0 + (t1 - t0) * i as f64 / (frames - 1) as f64
            };
            let name = format!("frame_{i:04}.ply");
            export_frame(trainer, t, &tmp.join(&name))?;
            index.push(json!({"file": name, "time": t}));
        }
        let doc = serde_json::to_vec_pretty(&json!({ "frames": index }))
            .map_err(|e| Error::Input(format!("frames.json: {e}")))?;
        write_atomic(&tmp.join("frames.json"), &doc)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    maaf_io::replace_dir(&tmp, out).map_err(|e| Error::io(out, e))?;
    Ok((0..frames)
        .map(|i| out.join(format!("frame_{i:04}.ply")))
        .collect())
}
