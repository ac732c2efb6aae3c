//! `maaf export-ply`: a trained dynamic run as standard 3DGS PLY frames.
//!
//! A frame at time `t` is what the renderer draws at `t`
//! ([`maaf_scene::forward::gaussians_at`]: deformed, with the 3D filter folded into scale
//! and opacity as Mip-Splatting's fused export does, `s' = sqrt(s^2 + var)`,
//! `o' = o sqrt(prod s^2 / prod(s^2 + var))`), stored in the Inria parameterisation
//! (`log s'`, `logit o'`, SH up to the degree the run renders with), so that any 3DGS
//! viewer shows the frame as `maaf render` does. Gaussians whose opacity at `t` is at
//! most 1/255 (SaRO's lifespan opacity outside a Gaussian's life, a pruned-looking
//! one) are left out: the renderer culls them ([`maaf_splat::compositing::ALPHA_MIN`]),
//! so the frame renders the same and the file is smaller.
//!
//! Every frame's header records how maaf draws it ([`FrameHeader`]: `comment maaf time
//! T`, `comment maaf background B`, `comment maaf filter2d mip|classic`), so that `maaf
//! render-ply` of an exported frame draws what `maaf render` does at that time.
//!
//! A sequence is a folder holding only `frame_0000.ply`, `frame_0001.ply`, ..., swapped
//! into place whole,
//! or the same files as one zip archive (`--out X.zip`). Only PLY files, because brush
//! plays a folder or zip as a sequence only when every file in it is a PLY (in natural
//! file-name order) and SuperSplat takes dropped files as a sequence only when all share
//! one prefix followed by a frame number (`docs/viewing.md`).

use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use maaf_autodiff::Tensor;
use maaf_autodiff::scalar::logit;
use maaf_data::Background;
use maaf_splat::ply::ply_bytes_with_comments;
use maaf_splat::{Filter2d, Gaussians};

use super::sequence::{check_own_folder, frame_times};
use maaf_splat::sh::num_coeffs;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

use crate::{Error, write_atomic};
use maaf_scene::TrainedScene;

/// The deformed, filtered Gaussians of `scene` at `time` as a static 3DGS scene, SH
/// truncated to the degree the run renders with ([`TrainedScene::render_settings`]), less
/// those the renderer culls at `time` (opacity at most 1/255).
pub fn frame_gaussians(scene: &TrainedScene, time: f64) -> Gaussians {
    let [means, scales, quats, opacity, sh] = scene.gaussians_at(time);
    let n = means.shape()[0];
    let stored = sh.shape()[1];
    let degree = scene.render_settings().sh_degree;
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
    // Kept unless surely culled: a NaN opacity stays so the export refuses it.
    let cutoff = maaf_splat::compositing::ALPHA_MIN as f32;
    let keep: Vec<usize> = (0..n)
        .filter(|&i| {
            let o = opacity.data()[i];
            o > cutoff || o.is_nan()
        })
        .collect();
    Gaussians {
        means: means.gather_rows(&keep),
        log_scales: scales.gather_rows(&keep).map(f32::ln),
        quats: quats.gather_rows(&keep),
        raw_opacity: opacity.gather_rows(&keep).map(logit),
        sh: Tensor::from_vec(sh_data, &[n, k, 3]).gather_rows(&keep),
        sh_degree: degree,
    }
}

/// [`frame_gaussians`], refused when a value is NaN or a centre, rotation or colour
/// is infinite (a log-scale or opacity logit of minus or plus infinity is a scale of
/// zero or an opacity of one, which a PLY can hold): a degenerate model exports
/// nothing rather than a file viewers cannot draw.
pub fn finite_frame_gaussians(scene: &TrainedScene, time: f64) -> Result<Gaussians, Error> {
    let g = frame_gaussians(scene, time);
    let fields = [
        ("centre", &g.means, true),
        ("rotation", &g.quats, true),
        ("colour", &g.sh, true),
        ("log-scale", &g.log_scales, false),
        ("opacity", &g.raw_opacity, false),
    ];
    for (name, values, finite) in fields {
        let bad = |v: &f32| if finite { !v.is_finite() } else { v.is_nan() };
        if let Some(i) = values.data().iter().position(bad) {
            let row = i / (values.len() / g.len().max(1)).max(1);
            return Err(Error::Input(format!(
                "t = {time}: Gaussian {row} has a non-finite {name} ({}): the model is degenerate at this time, nothing written",
                values.data()[i]
            )));
        }
    }
    Ok(g)
}

/// What an exported frame's header records besides the Gaussians: its time and how
/// the run draws it (background, screen-space filter), as `comment maaf KEY VALUE`
/// lines that 3DGS readers skip.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameHeader {
    /// The frame's time.
    pub time: Option<f64>,
    /// The run's background.
    pub background: Option<Background>,
    /// The run's screen-space filter.
    pub filter2d: Option<Filter2d>,
}

impl FrameHeader {
    /// The header of `scene`'s frame at `time`.
    pub fn of(scene: &TrainedScene, time: f64) -> Self {
        let settings = scene.render_settings();
        FrameHeader {
            time: Some(time),
            background: Some(Background(scene.record.background)),
            filter2d: Some(settings.filter2d),
        }
    }

    /// The `comment` lines (without the keyword) of the fields present.
    pub fn comments(&self) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(t) = self.time {
            lines.push(format!("maaf time {t}"));
        }
        if let Some(b) = self.background {
            lines.push(format!("maaf background {b}"));
        }
        if let Some(f) = self.filter2d {
            let name = match f {
                Filter2d::Classic => "classic",
                Filter2d::Mip => "mip",
            };
            lines.push(format!("maaf filter2d {name}"));
        }
        lines
    }

    /// Reads the fields back from a PLY's comment lines (comments not starting with
    /// `maaf `, and keys it does not know, are skipped); a value it cannot read is
    /// refused with a line naming `origin` and the comment.
    pub fn parse(comments: &[String], origin: &str) -> Result<Self, Error> {
        let mut header = FrameHeader::default();
        for line in comments {
            let Some(rest) = line.strip_prefix("maaf ") else {
                continue;
            };
            let bad = || Error::Input(format!("{origin}: header comment `{line}` cannot be read"));
            let (key, value) = rest.split_once(' ').ok_or_else(bad)?;
            match key {
                "time" => header.time = Some(value.parse().map_err(|_| bad())?),
                "background" => {
                    header.background = Some(Background::parse(value).map_err(|_| bad())?)
                }
                "filter2d" => {
                    header.filter2d = Some(match value {
                        "classic" => Filter2d::Classic,
                        "mip" => Filter2d::Mip,
                        _ => return Err(bad()),
                    })
                }
                _ => {}
            }
        }
        Ok(header)
    }
}

/// Writes the frame at `time` to `out` as a binary 3DGS PLY (atomically), its
/// [`FrameHeader`] in header comments; refuses non-finite Gaussians
/// ([`finite_frame_gaussians`]). Returns how many Gaussians it holds (those drawn at
/// `time`).
pub fn export_frame(scene: &TrainedScene, time: f64, out: &Path) -> Result<usize, Error> {
    let g = finite_frame_gaussians(scene, time)?;
    let header = FrameHeader::of(scene, time).comments();
    sweep_dead_temps(out)?;
    write_atomic(out, &ply_bytes_with_comments(&g, &header))?;
    Ok(g.len())
}

/// Removes what a killed export to `out` left beside it ([`maaf_io::remove_dead_temps`]).
pub(crate) fn sweep_dead_temps(out: &Path) -> Result<(), Error> {
    maaf_io::remove_dead_temps(out)
        .map(|_| ())
        .map_err(|e| Error::io(out, e))
}

/// Name of frame `i` of a sequence, `frame_NNNN.ply`.
fn frame_name(i: usize) -> String {
    format!("frame_{i:04}.ply")
}

/// Frame `time` as PLY bytes with its [`FrameHeader`], refused when non-finite
/// ([`finite_frame_gaussians`]).
fn frame_bytes(scene: &TrainedScene, time: f64) -> Result<Vec<u8>, Error> {
    let g = finite_frame_gaussians(scene, time)?;
    Ok(ply_bytes_with_comments(
        &g,
        &FrameHeader::of(scene, time).comments(),
    ))
}

/// Whether `out` names a zip archive (its extension is `zip`, any case): then
/// [`export_sequence_zip`] is the writer, else [`export_sequence`].
pub fn is_zip_path(out: &Path) -> bool {
    out.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("zip"))
}

/// Refuses an `out` that a sequence must not replace (see [`export_sequence`] and
/// [`export_sequence_zip`]), with one line naming the path; the CLI calls it before
/// loading the run so a bad `--out` fails at once.
pub fn check_sequence_target(out: &Path) -> Result<(), Error> {
    if is_zip_path(out) {
        check_zip_target(out)
    } else {
        check_sequence_folder(out)
    }
}

/// Refuses an `out` folder that a sequence must not replace: an existing file, or a
/// folder holding anything but the `frame_*.ply` (and the `frames.json` of exports
/// before the times moved into the PLY headers) of an earlier export.
fn check_sequence_folder(out: &Path) -> Result<(), Error> {
    if !out.exists() {
        return Ok(());
    }
    if !out.is_dir() {
        return Err(Error::Input(format!(
            "{}: exists and is not a folder; give a new folder, or a path ending in .zip",
            out.display()
        )));
    }
    check_own_folder(out, "export", |name| {
        name == "frames.json" || (name.starts_with("frame_") && name.ends_with(".ply"))
    })
}

/// Refuses a `.zip` target that is a folder or an existing file that is not a zip
/// archive (it does not start with a local file header `PK\x03\x04` or, for an
/// empty archive, the end-of-central-directory record `PK\x05\x06`).
fn check_zip_target(out: &Path) -> Result<(), Error> {
    if !out.exists() {
        return Ok(());
    }
    if out.is_dir() {
        return Err(Error::Input(format!(
            "{}: is a folder; a .zip sequence is written as one file",
            out.display()
        )));
    }
    let mut head = Vec::with_capacity(4);
    std::fs::File::open(out)
        .and_then(|f| f.take(4).read_to_end(&mut head))
        .map_err(|e| Error::io(out, e))?;
    if !(head == b"PK\x03\x04" || head == b"PK\x05\x06") {
        return Err(Error::Input(format!(
            "{}: exists and is not a zip archive; refusing to replace it",
            out.display()
        )));
    }
    Ok(())
}

/// Writes `frames` evenly spaced times over `[t0, t1]` (`t_i = t0 + (t1 - t0) i /
/// (frames - 1)`) into the folder `out` as `frame_0000.ply ...` (nothing else; each
/// frame's time in its header, `frame_bytes`), built in a temporary sibling and
/// swapped in whole. An existing file at `out`, or a folder holding other files, is refused.
/// Returns the PLY paths.
pub fn export_sequence(
    scene: &TrainedScene,
    range: (f64, f64),
    frames: usize,
    out: &Path,
) -> Result<Vec<PathBuf>, Error> {
    let times = frame_times(range, frames)?;
    check_sequence_folder(out)?;
    maaf_io::write_dir(out, Error::io, |tmp| {
        for (i, &t) in times.iter().enumerate() {
            write_atomic(&tmp.join(frame_name(i)), &frame_bytes(scene, t)?)?;
        }
        Ok(())
    })?;
    Ok((0..frames).map(|i| out.join(frame_name(i))).collect())
}

/// The same sequence as [`export_sequence`] as one zip archive `out`: the entries
/// `frame_0000.ply ...`, byte for byte the files of the folder
/// version, deflated, with the zip format's fixed default timestamp (1980-01-01) so
/// that equal runs give equal archives. The archive is streamed into a temporary
/// sibling and renamed into place ([`maaf_io::write_atomic_with`]: fsync, rename,
/// folder fsync); a folder at `out`, or an existing file that is not a zip archive, is
/// refused. Returns the archive's size in bytes.
pub fn export_sequence_zip(
    scene: &TrainedScene,
    range: (f64, f64),
    frames: usize,
    out: &Path,
) -> Result<u64, Error> {
    let times = frame_times(range, frames)?;
    check_zip_target(out)?;
    sweep_dead_temps(out)?;
    maaf_io::write_atomic_with(out, |file| {
        let mut zip = ZipWriter::new(FirstError::new(BufWriter::new(file)));
        let mut put = |name: &str, bytes: &[u8]| -> std::io::Result<()> {
            let options = SimpleFileOptions::default()
                .compression_method(CompressionMethod::Deflated)
                .large_file(bytes.len() as u64 >= u64::from(u32::MAX));
            zip.start_file(name, options)?;
            zip.write_all(bytes)
        };
        for (i, &t) in times.iter().enumerate() {
            // A refused frame fails the write, which removes the partial archive.
            let bytes = frame_bytes(scene, t).map_err(|e| std::io::Error::other(e.to_string()))?;
            put(&frame_name(i), &bytes)?;
        }
        zip.finish()?.flush()
    })
    .map_err(|e| Error::io(out, e))?;
    Ok(std::fs::metadata(out).map_err(|e| Error::io(out, e))?.len())
}

/// The archive's writer, which stops at its first error (a full disk): later writes
/// and seeks only move a virtual position. The zip writer finalises the archive when
/// dropped after an error and prints its own error as a debug line when that fails
/// too; here that clean-up writes into nothing (the temporary file is removed
/// anyway) and the one error reported is the first.
struct FirstError<W> {
    inner: W,
    failed: bool,
    pos: u64,
    end: u64,
}

impl<W> FirstError<W> {
    fn new(inner: W) -> Self {
        FirstError {
            inner,
            failed: false,
            pos: 0,
            end: 0,
        }
    }

    fn moved_to(&mut self, pos: u64) -> u64 {
        self.pos = pos;
        self.end = self.end.max(pos);
        pos
    }
}

impl<W: Write> Write for FirstError<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if !self.failed {
            match self.inner.write(buf) {
                Ok(n) => {
                    self.moved_to(self.pos + n as u64);
                    return Ok(n);
                }
                Err(e) => {
                    self.failed = true;
                    return Err(e);
                }
            }
        }
        self.moved_to(self.pos + buf.len() as u64);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if self.failed {
            return Ok(());
        }
        self.inner.flush().inspect_err(|_| self.failed = true)
    }
}

impl<W: Seek> Seek for FirstError<W> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        if !self.failed {
            let pos = self.inner.seek(to).inspect_err(|_| self.failed = true)?;
            return Ok(self.moved_to(pos));
        }
        let pos = match to {
            SeekFrom::Start(p) => p,
            SeekFrom::Current(d) => self.pos.saturating_add_signed(d),
            SeekFrom::End(d) => self.end.saturating_add_signed(d),
        };
        Ok(self.moved_to(pos))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_header_reads_back_what_it_writes_and_refuses_a_bad_value() {
        let header = FrameHeader {
            time: Some(0.25),
            background: Some(Background([0.5, 0.25, 1.0])),
            filter2d: Some(Filter2d::Classic),
        };
        let mut comments = header.comments();
        comments.insert(0, "written by another tool".into());
        assert_eq!(
            FrameHeader::parse(&comments, "f.ply").expect("reads"),
            header
        );
        assert_eq!(
            FrameHeader::parse(&[], "f.ply").expect("none"),
            FrameHeader::default()
        );
        let err = FrameHeader::parse(&["maaf background grey".into()], "f.ply")
            .expect_err("refused")
            .to_string();
        assert!(
            err.contains("f.ply") && err.contains("maaf background grey"),
            "{err}"
        );
    }
}
