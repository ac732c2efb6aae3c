//! Image metrics of a render against its ground truth (docs/conventions.md,
//! "Metrics"): PSNR, SSIM and per-pixel error maps, shared by the trainer's validation
//! and by evaluation (`maaf_eval::metrics` adds the region, ring, temporal and popping
//! metrics). Not differentiable; every sum is accumulated in f64 whatever the image
//! type.
//!
//! Images are `[H, W, C]` tensors with values on [0, 1] (data range 1). The SSIM here
//! is the *evaluation* convention of scikit-image, which crops the border, and differs
//! from the training loss (`maaf_train::loss::ssim`, zero-padded over the full map; both take their
//! window from [`ssim_window`]).
//! Both are pinned: this one against scikit-image 0.26 values stored in
//! `scene/tests/fixtures/metric_fixtures.txt`.

pub mod ssim_window;

use std::fmt;

use maaf_autodiff::{Float, Tensor};

use ssim_window::{SSIM_C1, SSIM_C2, SSIM_SIGMA, SSIM_WINDOW, blur_same, gaussian_taps};

/// Why a metric could not be computed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MetricError {
    /// The two images do not have the same `[H, W, C]` shape.
    ShapeMismatch {
        /// Shape of the render.
        render: Vec<usize>,
        /// Shape of the ground truth.
        gt: Vec<usize>,
    },
    /// The tensor is not a non-empty `[H, W, C]` image.
    NotAnImage {
        /// The offending shape.
        shape: Vec<usize>,
    },
    /// The image is smaller than the 11 x 11 SSIM window (scikit-image refuses it too).
    TooSmallForSsim {
        /// Image height.
        height: usize,
        /// Image width.
        width: usize,
    },
}

impl fmt::Display for MetricError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MetricError::ShapeMismatch { render, gt } => {
                write!(
                    f,
                    "render shape {render:?} differs from ground truth shape {gt:?}"
                )
            }
            MetricError::NotAnImage { shape } => {
                write!(
                    f,
                    "expected a non-empty [H, W, C] image, got shape {shape:?}"
                )
            }
            MetricError::TooSmallForSsim { height, width } => write!(
                f,
                "a {height}x{width} image is smaller than the {SSIM_WINDOW}x{SSIM_WINDOW} SSIM window"
            ),
        }
    }
}

impl std::error::Error for MetricError {}

/// `(H, W, C)` of two images of equal shape, or why not.
pub fn image_dims<T: Float>(
    render: &Tensor<T>,
    gt: &Tensor<T>,
) -> Result<(usize, usize, usize), MetricError> {
    let s = render.shape();
    if s.len() != 3 || s.contains(&0) {
        return Err(MetricError::NotAnImage { shape: s.to_vec() });
    }
    if gt.shape() != s {
        return Err(MetricError::ShapeMismatch {
            render: s.to_vec(),
            gt: gt.shape().to_vec(),
        });
    }
    Ok((s[0], s[1], s[2]))
}

/// `(H, W, C)` of two images of equal shape with a `[H, W]` mask (a coverage map), or
/// why not.
pub fn masked_dims<T: Float>(
    render: &Tensor<T>,
    gt: &Tensor<T>,
    mask: &[f32],
) -> Result<(usize, usize, usize), MetricError> {
    let (h, w, c) = image_dims(render, gt)?;
    if mask.len() != h * w {
        return Err(MetricError::NotAnImage {
            shape: vec![h, w, c, mask.len()],
        });
    }
    Ok((h, w, c))
}

/// Mean squared error `MSE = (1 / HWC) sum (render - gt)^2`, accumulated in f64.
pub fn mse<T: Float>(render: &Tensor<T>, gt: &Tensor<T>) -> Result<f64, MetricError> {
    image_dims(render, gt)?;
    let total: f64 = render
        .data()
        .iter()
        .zip(gt.data())
        .map(|(&a, &b)| {
            let d = Float::to_f64(a) - Float::to_f64(b);
            d * d
        })
        .sum();
    Ok(total / render.len() as f64)
}

/// Peak signal-to-noise ratio of one image on [0, 1]: `PSNR = 10 log10(1 / MSE)` dB,
/// MSE over all `H W C` values (3DGS `utils/image_utils.py::psnr`, scikit-image
/// `peak_signal_noise_ratio(gt, render, data_range=1)`). Identical images give
/// `f64::INFINITY` (never NaN), as scikit-image does. Report the mean of per-image
/// values over a test set (docs/conventions.md, "Metrics").
pub fn psnr<T: Float>(render: &Tensor<T>, gt: &Tensor<T>) -> Result<f64, MetricError> {
    let m = mse(render, gt)?;
    Ok(if m == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / m).log10()
    })
}

/// Mean SSIM of one image, exactly as scikit-image's
/// `structural_similarity(render, gt, channel_axis=2, gaussian_weights=True, sigma=1.5,
/// use_sample_covariance=False, data_range=1)`:
///
/// - per channel, Gaussian-weighted moments with sigma 1.5 truncated at 3.5 sigma, i.e.
///   radius `int(3.5 * 1.5 + 0.5) = 5`, an 11 x 11 window (taps
///   [`gaussian_taps`]`(11, 1.5)`); population (not sample) covariances;
/// - `S = (2 mu_x mu_y + C1)(2 s_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(s_xx + s_yy + C2))`,
///   `C1 = 0.01^2`, `C2 = 0.03^2` (Wang et al. 2004);
/// - the map is cropped by the window radius (5 pixels each side) and averaged, so
///   scikit-image's reflect padding never enters the result; then the mean over
///   channels.
///
/// Needs `H, W >= 11`. Symmetric in its arguments.
pub fn ssim<T: Float>(render: &Tensor<T>, gt: &Tensor<T>) -> Result<f64, MetricError> {
    let (h, w, c) = image_dims(render, gt)?;
    if h < SSIM_WINDOW || w < SSIM_WINDOW {
        return Err(MetricError::TooSmallForSsim {
            height: h,
            width: w,
        });
    }
    let x: Vec<f64> = render.data().iter().map(|&v| Float::to_f64(v)).collect();
    let y: Vec<f64> = gt.data().iter().map(|&v| Float::to_f64(v)).collect();
    let taps = gaussian_taps(SSIM_WINDOW, SSIM_SIGMA);
    // Zero "same" padding: the cropped interior only reads in-range samples, so it
    // equals scikit-image's reflect-padded filter there.
    let blur = |v: &[f64]| blur_same(v, h, w, c, &taps);
    let prod = |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(p, q)| p * q).collect() };
    let (mu_x, mu_y) = (blur(&x), blur(&y));
    let (e_xx, e_yy, e_xy) = (
        blur(&prod(&x, &x)),
        blur(&prod(&y, &y)),
        blur(&prod(&x, &y)),
    );
    let r = SSIM_WINDOW / 2;
    let mut per_channel = vec![0.0f64; c];
    for i in r..h - r {
        for j in r..w - r {
            for (ch, acc) in per_channel.iter_mut().enumerate() {
                let k = (i * w + j) * c + ch;
                let (mx, my) = (mu_x[k], mu_y[k]);
                let a1 = 2.0 * mx * my + SSIM_C1;
                let a2 = 2.0 * (e_xy[k] - mx * my) + SSIM_C2;
                let b1 = mx * mx + my * my + SSIM_C1;
                let b2 = (e_xx[k] - mx * mx) + (e_yy[k] - my * my) + SSIM_C2;
                *acc += a1 * a2 / (b1 * b2);
            }
        }
    }
    let n = ((h - 2 * r) * (w - 2 * r)) as f64;
    Ok(per_channel.iter().map(|s| s / n).sum::<f64>() / c as f64)
}

/// PSNR and SSIM of one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageMetrics {
    /// [`psnr`], dB.
    pub psnr: f64,
    /// [`ssim`].
    pub ssim: f64,
}

/// [`psnr`] and [`ssim`] of one render against its ground truth.
pub fn image_metrics<T: Float>(
    render: &Tensor<T>,
    gt: &Tensor<T>,
) -> Result<ImageMetrics, MetricError> {
    Ok(ImageMetrics {
        psnr: psnr(render, gt)?,
        ssim: ssim(render, gt)?,
    })
}

/// Mean of per-image metrics over a set of views (the reported numbers: the mean of
/// per-image PSNR, not the PSNR of the pooled MSE). `None` for an empty set.
pub fn mean_metrics(per_image: &[ImageMetrics]) -> Option<ImageMetrics> {
    if per_image.is_empty() {
        return None;
    }
    let n = per_image.len() as f64;
    Some(ImageMetrics {
        psnr: per_image.iter().map(|m| m.psnr).sum::<f64>() / n,
        ssim: per_image.iter().map(|m| m.ssim).sum::<f64>() / n,
    })
}

/// Per-pixel error map `E[i, j] = (1 / C) sum_c |render[i, j, c] - gt[i, j, c]|`,
/// shape `[H, W]`, on [0, 1] for images on [0, 1] (for the eval's error images).
pub fn error_map<T: Float>(render: &Tensor<T>, gt: &Tensor<T>) -> Result<Tensor<T>, MetricError> {
    let (h, w, c) = image_dims(render, gt)?;
    let data = render
        .data()
        .chunks_exact(c)
        .zip(gt.data().chunks_exact(c))
        .map(|(a, b)| {
            let s: f64 = a
                .iter()
                .zip(b)
                .map(|(&p, &q)| (Float::to_f64(p) - Float::to_f64(q)).abs())
                .sum();
            T::of(s / c as f64)
        })
        .collect();
    Ok(Tensor::from_vec(data, &[h, w]))
}
