//! Reading converted LPIPS weights (safetensors, written by
//! `lpips/tools/convert_weights.py`): `conv{i}.weight` `[k, k, c_in, c_out]` and
//! `conv{i}.bias` `[c_out]` for every stage `i` of the network, `lin{l}.weight` `[c]` for
//! each of the five tapped maps.

use std::path::Path;

use safetensors::{Dtype, SafeTensors};

use crate::LpipsError;
use crate::backbone::{Backbone, Net};
use crate::layers::ConvRelu;

/// The backbone `net` and its five v0.1 linear-layer weight vectors read from `path`.
pub(crate) fn load(net: Net, path: &Path) -> Result<(Backbone, Vec<Vec<f32>>), LpipsError> {
    let bytes = std::fs::read(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => LpipsError::WeightsMissing {
            net,
            path: path.to_path_buf(),
        },
        _ => invalid(path, format!("cannot read: {e}")),
    })?;
    let st = SafeTensors::deserialize(&bytes)
        .map_err(|e| invalid(path, format!("not a safetensors file: {e}")))?;
    let stages = net.stages();
    let mut convs = Vec::with_capacity(stages.len());
    let mut lins = Vec::with_capacity(5);
    for (i, l) in stages.iter().enumerate() {
        let weight = tensor(
            &st,
            path,
            &format!("conv{i}.weight"),
            &[l.k, l.k, l.c_in, l.c_out],
        )?;
        let bias = tensor(&st, path, &format!("conv{i}.bias"), &[l.c_out])?;
        if l.tap {
            let name = format!("lin{}.weight", lins.len());
            lins.push(tensor(&st, path, &name, &[l.c_out])?);
        }
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
    Ok((Backbone { net, convs }, lins))
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
