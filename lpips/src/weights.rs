//! Reading the converted LPIPS AlexNet weights (safetensors, written by
//! `lpips/tools/convert_weights.py`).

use std::path::{Path, PathBuf};

use safetensors::{Dtype, SafeTensors};

use crate::LpipsError;
use crate::alexnet::{AlexNet, LAYERS};
use crate::layers::ConvRelu;

/// Environment variable that overrides the weights path of [`default_weights_path`].
pub const WEIGHTS_ENV: &str = "MAAF_LPIPS_WEIGHTS";

/// The committed weights file, `lpips/weights/alex_v0.1.safetensors` in the source tree.
pub const DEFAULT_WEIGHTS: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/weights/alex_v0.1.safetensors");

/// Where [`crate::Lpips::load_default`] reads the weights: `$MAAF_LPIPS_WEIGHTS` when set
/// and non-empty, else [`DEFAULT_WEIGHTS`].
pub fn default_weights_path() -> PathBuf {
    match std::env::var_os(WEIGHTS_ENV) {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => PathBuf::from(DEFAULT_WEIGHTS),
    }
}

/// The backbone and the five v0.1 linear-layer weight vectors read from `path`.
pub(crate) fn load(path: &Path) -> Result<(AlexNet, Vec<Vec<f32>>), LpipsError> {
    let bytes = std::fs::read(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => LpipsError::WeightsMissing {
            path: path.to_path_buf(),
        },
        _ => invalid(path, format!("cannot read: {e}")),
    })?;
    let st = SafeTensors::deserialize(&bytes)
        .map_err(|e| invalid(path, format!("not a safetensors file: {e}")))?;
    let mut convs = Vec::with_capacity(LAYERS.len());
    let mut lins = Vec::with_capacity(LAYERS.len());
    for (i, l) in LAYERS.iter().enumerate() {
        let weight = tensor(
            &st,
            path,
            &format!("conv{i}.weight"),
            &[l.k, l.k, l.c_in, l.c_out],
        )?;
        let bias = tensor(&st, path, &format!("conv{i}.bias"), &[l.c_out])?;
        lins.push(tensor(&st, path, &format!("lin{i}.weight"), &[l.c_out])?);
        convs.push(ConvRelu {
            k: l.k,
            stride: l.stride,
            pad: l.pad,
            c_in: l.c_in,
            c_out: l.c_out,
            weight,
            bias,
        });
    }
    Ok((AlexNet { convs }, lins))
}

fn invalid(path: &Path, message: String) -> LpipsError {
    LpipsError::WeightsInvalid {
        path: path.to_path_buf(),
        message,
    }
}

/// The f32 tensor `name` of shape `shape`, or an error naming the tensor.
fn tensor(
    st: &SafeTensors<'_>,
    path: &Path,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f32>, LpipsError> {
    let view = st
        .tensor(name)
        .map_err(|e| invalid(path, format!("tensor `{name}`: {e}")))?;
    if view.dtype() != Dtype::F32 || view.shape() != shape {
        return Err(invalid(
            path,
            format!(
                "tensor `{name}` is {:?} {:?}, expected F32 {shape:?}",
                view.dtype(),
                view.shape()
            ),
        ));
    }
    Ok(view
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}
