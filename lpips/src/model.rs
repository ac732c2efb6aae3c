//! The LPIPS distance: scaling layer, backbone features (AlexNet or VGG16), unit-normalised
//! squared differences weighted by the v0.1 linear layers, spatial mean, sum over layers.

use std::path::Path;

use maaf_autodiff::{Float, Tensor};
use rayon::prelude::*;

use crate::LpipsError;
use crate::backbone::{Backbone, Net};
use crate::layers::FeatureMap;
use crate::weights::load;

/// LPIPS scaling-layer shift (per RGB channel), applied to inputs on `[-1, 1]`.
const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
/// LPIPS scaling-layer scale (per RGB channel).
const SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// Added to the channel norm before dividing (LPIPS `normalize_tensor`).
const NORM_EPS: f32 = 1e-10;

/// A loaded LPIPS model (a backbone and its v0.1 linear layers). Cheap to share between
/// threads (`&Lpips` is all [`Lpips::distance`] needs).
pub struct Lpips {
    net: Backbone,
    /// `w^l_c >= 0`, one vector per layer.
    lins: Vec<Vec<f32>>,
}

impl Lpips {
    /// Loads `net`'s weights from [`Net::default_weights_path`] (for AlexNet the
    /// committed `lpips/weights/alex_v0.1.safetensors`, or `$MAAF_LPIPS_WEIGHTS`).
    pub fn load_default(net: Net) -> Result<Lpips, LpipsError> {
        Lpips::load(net, &net.default_weights_path())
    }

    /// Loads `net`'s weights from a safetensors file written by
    /// `lpips/tools/convert_weights.py`. A missing file gives
    /// [`LpipsError::WeightsMissing`]; a wrong tensor name, dtype or shape (another
    /// network's file among them) gives [`LpipsError::WeightsInvalid`] naming it.
    pub fn load(net: Net, path: &Path) -> Result<Lpips, LpipsError> {
        let (net, lins) = load(net, path)?;
        Ok(Lpips { net, lins })
    }

    /// The backbone this model compares features of.
    pub fn net(&self) -> Net {
        self.net.net
    }

    /// LPIPS distance of two `[H, W, 3]` RGB images with values on `[0, 1]` (no
    /// resizing, `H, W >=` [`Net::min_size`]); symmetric, `>= 0`, exactly 0 for identical
    /// images. See the crate documentation for the formula. Values are converted to
    /// f32 (the network runs in f32); the per-layer means are summed in f64.
    pub fn distance<T: Float>(&self, a: &Tensor<T>, b: &Tensor<T>) -> Result<f64, LpipsError> {
        if a.shape() != b.shape() {
            return Err(LpipsError::ShapeMismatch {
                a: a.shape().to_vec(),
                b: b.shape().to_vec(),
            });
        }
        let fa = self.features(a)?;
        let fb = self.features(b)?;
        Ok(fa
            .iter()
            .zip(&fb)
            .zip(&self.lins)
            .map(|((x, y), w)| weighted_mean_sq_diff(x, y, w))
            .sum())
    }

    /// The five unit-normalised feature maps of one image.
    fn features<T: Float>(&self, img: &Tensor<T>) -> Result<Vec<FeatureMap>, LpipsError> {
        let s = img.shape();
        if s.len() != 3 || s[2] != 3 || s[0] == 0 || s[1] == 0 {
            return Err(LpipsError::NotAnImage { shape: s.to_vec() });
        }
        let (h, w) = (s[0], s[1]);
        let min = self.net().min_size();
        if h < min || w < min {
            return Err(LpipsError::TooSmall {
                net: self.net(),
                height: h,
                width: w,
            });
        }
        let data = img
            .data()
            .chunks_exact(3)
            .flat_map(|px| {
                (0..3).map(move |c| (2.0 * Float::to_f64(px[c]) as f32 - 1.0 - SHIFT[c]) / SCALE[c])
            })
            .collect();
        let x = FeatureMap { h, w, c: 3, data };
        let mut feats = self.net.features(&x).ok_or(LpipsError::TooSmall {
            net: self.net(),
            height: h,
            width: w,
        })?;
        for f in &mut feats {
            unit_normalise(f);
        }
        Ok(feats)
    }
}

/// `f / (|f|_2 + 1e-10)` at every pixel, the norm taken over channels.
fn unit_normalise(f: &mut FeatureMap) {
    let c = f.c;
    f.data.par_chunks_mut(c).for_each(|px| {
        let norm = px.iter().map(|v| v * v).sum::<f32>().sqrt();
        let inv = 1.0 / (norm + NORM_EPS);
        px.iter_mut().for_each(|v| *v *= inv);
    });
}

/// `(1 / (H W)) sum_{h,w} sum_c w_c (x_hwc - y_hwc)^2`, accumulated in f64.
fn weighted_mean_sq_diff(x: &FeatureMap, y: &FeatureMap, w: &[f32]) -> f64 {
    let total: f64 = x
        .data
        .par_chunks(x.c)
        .zip(y.data.par_chunks(y.c))
        .map(|(p, q)| {
            p.iter()
                .zip(q)
                .zip(w)
                .map(|((&a, &b), &wc)| {
                    let d = a - b;
                    wc * d * d
                })
                .sum::<f32>() as f64
        })
        .sum();
    total / (x.h * x.w) as f64
}
