//! The views of a [`Dataset`] and their image cache: decoding each view once,
//! box-downsampling it to every requested factor (premultiplied, then composited on the
//! background; the alpha kept as the view's coverage when the source has any
//! transparency) in parallel, and handing out cached views.

use std::sync::Arc;

use rayon::prelude::*;

use super::{CacheKey, CachedImage, Dataset, View};
use crate::dnerf::Split;
use crate::downsample::{box_downsample, composite_premultiplied, premultiply};
use crate::error::DataError;
use crate::image::{Image, decode_rgba};

impl Dataset {
    /// One view at `scale`; decodes its image only if this (view, scale) is not cached.
    pub fn view(&self, split: Split, index: usize, scale: f64) -> Result<View, DataError> {
        let k = self.factor(split, scale)?;
        self.load(split, &[index], &[k])?;
        self.cached_view(split, index, k)
    }

    /// All views of a split at `scale` (decoded in parallel on first use, then cached).
    pub fn views(&self, split: Split, scale: f64) -> Result<Vec<View>, DataError> {
        let k = self.factor(split, scale)?;
        let all: Vec<usize> = (0..self.len(split)).collect();
        self.load(split, &all, &[k])?;
        all.into_iter()
            .map(|i| self.cached_view(split, i, k))
            .collect()
    }

    /// Training views at `scale`.
    pub fn train_views(&self, scale: f64) -> Result<Vec<View>, DataError> {
        self.views(Split::Train, scale)
    }

    /// Test views at `scale`.
    pub fn test_views(&self, scale: f64) -> Result<Vec<View>, DataError> {
        self.views(Split::Test, scale)
    }

    /// Decodes the views `indices` of `split` once each and fills the cache for all
    /// `scales` at once (the multi-scale evaluation asks for several scales of the same
    /// test images).
    pub fn preload(
        &self,
        split: Split,
        indices: &[usize],
        scales: &[f64],
    ) -> Result<(), DataError> {
        let ks = scales
            .iter()
            .map(|&s| self.factor(split, s))
            .collect::<Result<Vec<u32>, _>>()?;
        self.load(split, indices, &ks)
    }

    /// Drops every cached image of `split` (the trainer keeps its own copy of the
    /// training images; a later request decodes them again).
    pub fn evict(&self, split: Split) {
        if let Ok(mut cache) = self.cache.lock() {
            cache.retain(|(s, _, _), _| *s != split);
        }
    }

    /// Number of (view, scale) images currently cached.
    pub fn cached_images(&self) -> usize {
        self.cache.lock().map_or(0, |c| c.len())
    }
}

impl Dataset {
    /// The cached image of view `index` at factor `k` as a [`View`] with its camera
    /// scaled by `1 / k`; [`Dataset::load`] must have filled that entry.
    pub(super) fn cached_view(
        &self,
        split: Split,
        index: usize,
        k: u32,
    ) -> Result<View, DataError> {
        let frame = self.frame(split, index)?;
        let (image, coverage) = self
            .cache
            .lock()
            .ok()
            .and_then(|c| c.get(&(split, k, index)).cloned())
            .ok_or_else(|| DataError::request(&frame.file, "image cache lost an entry"))?;
        Ok(View {
            split,
            index,
            image,
            coverage,
            camera: frame.camera.scaled(1.0 / k as f64),
            time: frame.time,
        })
    }

    /// Decodes the listed views once each and inserts every missing factor.
    pub(super) fn load(
        &self,
        split: Split,
        indices: &[usize],
        ks: &[u32],
    ) -> Result<(), DataError> {
        let meta = self.split(split)?;
        let missing: Vec<(usize, Vec<u32>)> = {
            let cache = self
                .cache
                .lock()
                .map_err(|_| DataError::request(&meta.json, "image cache poisoned"))?;
            indices
                .iter()
                .map(|&i| {
                    let ks: Vec<u32> = ks
                        .iter()
                        .copied()
                        .filter(|&k| !cache.contains_key(&(split, k, i)))
                        .collect();
                    (i, ks)
                })
                .filter(|(_, ks)| !ks.is_empty())
                .collect()
        };
        let background = self.background;
        let decoded: Vec<Vec<(CacheKey, CachedImage)>> =
            missing
                .par_iter()
                .map(|(i, ks)| {
                    let frame = self.frame(split, *i)?;
                    let mut rgba = decode_rgba(&frame.file)?;
                    if (rgba.width, rgba.height) != (meta.width, meta.height) {
                        return Err(DataError::field(
                            &meta.json,
                            format!("frames[{i}].file_path"),
                            format!(
                                "{} decodes to {}x{} but the split is {}x{}",
                                frame.file.display(),
                                rgba.width,
                                rgba.height,
                                meta.width,
                                meta.height
                            ),
                        ));
                    }
                    let opaque = rgba.data.chunks_exact(4).all(|p| p[3] >= 1.0);
                    premultiply(&mut rgba.data);
                    let (w, h) = (rgba.width as usize, rgba.height as usize);
                    ks.iter()
                        .map(|&k| {
                            let small = box_downsample(&rgba.data, w, h, 4, k as usize)
                                .ok_or_else(|| DataError::Scale {
                                    path: meta.json.display().to_string(),
                                    scale: 1.0 / k as f64,
                                    message: format!("factor {k} does not divide {w}x{h}"),
                                })?;
                            let (width, height) = (rgba.width / k, rgba.height / k);
                            let img = Image {
                                width,
                                height,
                                channels: 3,
                                data: composite_premultiplied(&small, background),
                            };
                            let coverage = (!opaque).then(|| {
                                Arc::new(Image {
                                    width,
                                    height,
                                    channels: 1,
                                    data: small.chunks_exact(4).map(|p| p[3]).collect(),
                                })
                            });
                            Ok(((split, k, *i), (Arc::new(img), coverage)))
                        })
                        .collect()
                })
                .collect::<Result<_, DataError>>()?;
        let mut cache = self
            .cache
            .lock()
            .map_err(|_| DataError::request(&meta.json, "image cache poisoned"))?;
        for (key, img) in decoded.into_iter().flatten() {
            cache.entry(key).or_insert(img);
        }
        Ok(())
    }
}
