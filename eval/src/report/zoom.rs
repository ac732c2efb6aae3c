//! Pictures made to be seen: zoomed-out renders enlarged without interpolation (a
//! 25-pixel render is a blur when a viewer scales it up, and unreadable at its own
//! size), and the composite the README shows, `zoom.png`: one test view's ground truth
//! and every run's render at the smallest scale (enlarged) above the same at the
//! largest scale (a centre crop), side by side.

use std::path::{Path, PathBuf};

use image::imageops::{self, FilterType};
use image::{Rgb, RgbImage};

use super::ReportRun;
use crate::images::save_png;
use crate::{Error, scale_label, write_atomic};

/// The composite's file name in the report folder.
pub const ZOOM_FIGURE: &str = "zoom.png";

/// White gap between the composite's tiles, pixels.
const GAP: u32 = 6;

/// How many times a picture rendered at `scale` is enlarged to be seen: `1/scale`
/// below the training scale (back to the 1x size), else 1.
pub fn enlargement(scale: f64) -> u32 {
    if scale < 1.0 {
        (1.0 / scale).round().max(1.0) as u32
    } else {
        1
    }
}

fn read(path: &Path) -> Result<RgbImage, Error> {
    Ok(image::open(path)
        .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?
        .to_rgb8())
}

/// Copies the PNG `from` to `to` (crash-safely), enlarged `factor` times by repeating
/// pixels when `factor` > 1.
pub fn copy_enlarged(from: &Path, to: &Path, factor: u32) -> Result<(), Error> {
    if factor <= 1 {
        let bytes = std::fs::read(from).map_err(|e| Error::io(from, e))?;
        return write_atomic(to, &bytes);
    }
    let img = read(from)?;
    let (w, h) = img.dimensions();
    save_png(
        &imageops::resize(&img, w * factor, h * factor, FilterType::Nearest),
        to,
    )
}

/// `img` as a `(w, h)` tile: enlarged without interpolation when smaller, centre-cropped
/// when larger.
fn tile(img: &RgbImage, (w, h): (u32, u32)) -> RgbImage {
    let img = if img.width() < w {
        imageops::resize(img, w, h, FilterType::Nearest)
    } else {
        img.clone()
    };
    let (x, y) = (
        (img.width() - w.min(img.width())) / 2,
        (img.height() - h.min(img.height())) / 2,
    );
    imageops::crop_imm(&img, x, y, w, h).to_image()
}

/// The images of one row: the ground truth and each run's render of `view` at `scale`,
/// or `None` when one of them was not saved.
fn row(runs: &[ReportRun], scale: f64, view: usize) -> Option<Vec<PathBuf>> {
    let dir = |r: &ReportRun| r.dir.join("eval").join(scale_label(scale));
    let gt = runs
        .iter()
        .map(|r| dir(r).join(format!("gt_{view:03}.png")))
        .find(|p| p.is_file())?;
    let renders = runs
        .iter()
        .map(|r| dir(r).join(format!("render_{view:03}.png")));
    let all: Vec<PathBuf> = std::iter::once(gt).chain(renders).collect();
    all.iter().all(|p| p.is_file()).then_some(all)
}

/// Writes `OUT/zoom.png` for the smallest and the largest of `scales` (one below and
/// one above 1x needed): the first test view every run saved at both, each tile as
/// large as three times the 1x image (at most the largest render), and returns its
/// path; `None` (nothing written) when the runs lack such pictures.
pub fn zoom_figure(
    runs: &[ReportRun],
    scales: &[f64],
    out: &Path,
) -> Result<Option<PathBuf>, Error> {
    let (Some(&small), Some(&large)) = (scales.first(), scales.last()) else {
        return Ok(None);
    };
    if !(small < 1.0 && large > 1.0) || runs.is_empty() {
        return Ok(None);
    }
    let Some((top, bottom)) =
        (0..1000).find_map(|v| Some((row(runs, small, v)?, row(runs, large, v)?)))
    else {
        return Ok(None);
    };
    let big = read(&bottom[0])?;
    let side = |n: u32| (3.0 * f64::from(n) / large).round().min(f64::from(n)) as u32;
    let size = (side(big.width()), side(big.height()));
    let columns = top.len() as u32;
    let mut figure = RgbImage::from_pixel(
        columns * size.0 + (columns - 1) * GAP,
        2 * size.1 + GAP,
        Rgb([255, 255, 255]),
    );
    for (r, paths) in [top, bottom].iter().enumerate() {
        for (c, p) in paths.iter().enumerate() {
            let t = tile(&read(p)?, size);
            let (x, y) = (c as u32 * (size.0 + GAP), r as u32 * (size.1 + GAP));
            imageops::replace(&mut figure, &t, i64::from(x), i64::from(y));
        }
    }
    let path = out.join(ZOOM_FIGURE);
    save_png(&figure, &path)?;
    Ok(Some(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(path: &Path, (w, h): (u32, u32), v: u8) {
        save_png(&RgbImage::from_pixel(w, h, Rgb([v, v, v])), path).expect("png");
    }

    #[test]
    fn the_composite_enlarges_the_small_renders_and_crops_the_large_ones() {
        let root = std::env::temp_dir().join(format!("maaf-zoom-{}", std::process::id()));
        let mut runs = Vec::new();
        for (k, name) in ["none", "motion"].iter().enumerate() {
            for (scale, side) in [(0.25, 5), (4.0, 80)] {
                let dir = root.join(name).join("eval").join(scale_label(scale));
                std::fs::create_dir_all(&dir).expect("dir");
                solid(&dir.join("render_002.png"), (side, side), 100 + k as u8);
                solid(&dir.join("gt_002.png"), (side, side), 250);
            }
            let mut run = ReportRun::for_test(name, "saro", name, Vec::new());
            run.dir = root.join(name);
            runs.push(run);
        }
        let path = zoom_figure(&runs, &[0.25, 1.0, 4.0], &root)
            .expect("written")
            .expect("pictures found");
        let fig = image::open(&path).expect("png").to_rgb8();
        // 1x is 20 px, so tiles of 60 px: 3 columns and 2 rows with their gaps.
        assert_eq!(fig.dimensions(), (3 * 60 + 2 * GAP, 2 * 60 + GAP));
        assert_eq!(
            fig.get_pixel(0, 0),
            &Rgb([250, 250, 250]),
            "ground truth first"
        );
        assert_eq!(fig.get_pixel(60 + GAP + 59, 59), &Rgb([100, 100, 100]));
        assert_eq!(
            fig.get_pixel(2 * (60 + GAP), 60 + GAP),
            &Rgb([101, 101, 101])
        );
        assert!(
            zoom_figure(&runs, &[1.0, 4.0], &root)
                .expect("ok")
                .is_none()
        );

        let small = root.join("none/eval/0.25x/render_002.png");
        let enlarged = root.join("big.png");
        copy_enlarged(&small, &enlarged, enlargement(0.25)).expect("enlarged");
        assert_eq!(
            image::open(&enlarged).expect("png").to_rgb8().dimensions(),
            (20, 20)
        );
        let _ = std::fs::remove_dir_all(&root);
    }
}
