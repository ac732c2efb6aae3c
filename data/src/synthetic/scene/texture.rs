//! Procedural textures of the analytic scene: functions of the local surface point, so
//! a point keeps its colour as its object moves.

use glam::DVec3;

/// Procedural textures, functions of the local surface point (and local normal).
#[derive(Clone, Copy, Debug)]
pub enum Texture {
    /// One colour.
    Plain([f64; 3]),
    /// Floor: 0.2-unit checker of two tones plus dark grid lines 0.01 wide every 0.05
    /// units, and thin concentric rings near the rim.
    Floor,
    /// Backdrop (front face, local x-z): bands of text-like glyphs at three sizes, a
    /// chirp of square-wave stripes whose frequency rises from 2 to 60 cycles per unit,
    /// and a checker with fine diagonal stripes.
    Backdrop,
    /// Sphere: latitude-longitude checker (`lon` x `lat` cells) with thin meridian lines.
    SphereChecker {
        /// Cells around the equator.
        lon: u32,
        /// Cells from pole to pole.
        lat: u32,
        /// First colour.
        a: [f64; 3],
        /// Second colour.
        b: [f64; 3],
    },
    /// Box faces: diagonal square-wave stripes of the given period, two colours.
    Stripes {
        /// Stripe period in local units (half of it per colour).
        period: f64,
        /// First colour.
        a: [f64; 3],
        /// Second colour.
        b: [f64; 3],
    },
}

fn mix(a: [f64; 3], b: [f64; 3], w: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * w,
        a[1] + (b[1] - a[1]) * w,
        a[2] + (b[2] - a[2]) * w,
    ]
}

/// `true` on the "odd" cells of a checker of the given cell size.
fn checker(u: f64, v: f64, cell: f64) -> bool {
    ((u / cell).floor() as i64 + (v / cell).floor() as i64).rem_euclid(2) == 1
}

/// `true` inside lines of `width` repeating every `period` (lines centred on multiples).
fn lines(u: f64, period: f64, width: f64) -> bool {
    let f = (u / period + 0.5).rem_euclid(1.0) - 0.5;
    f.abs() * period < 0.5 * width
}

/// Integer hash to `[0, 1)` (splitmix64 finaliser).
pub(crate) fn hash01(a: i64, b: i64, c: i64) -> f64 {
    let mut x = (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (c as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    x ^= x >> 30;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^= x >> 31;
    (x >> 11) as f64 / (1u64 << 53) as f64
}

/// Text-like glyphs: a line of 5x7-cell glyphs of height `size` (advance 6 cells, line
/// pitch 9 cells), each glyph a hashed bitmap, with hashed word gaps. `true` on ink.
fn glyph_ink(u: f64, v: f64, size: f64, salt: i64) -> bool {
    let cell = size / 7.0;
    let cu = (u / cell).floor() as i64;
    let cv = (v / cell).floor() as i64;
    let (gx, sx) = (cu.div_euclid(6), cu.rem_euclid(6));
    let (gy, sy) = (cv.div_euclid(9), cv.rem_euclid(9));
    if sx >= 5 || sy >= 7 {
        return false;
    }
    if hash01(gx, gy, salt + 1) < 0.18 {
        return false; // a space between words
    }
    // Strokes: a left or right vertical stem and a few bars make glyphs look like letters.
    let stem = hash01(gx, gy, salt + 2);
    if (stem < 0.5 && sx == 0) || (stem >= 0.5 && sx == 4) {
        return true;
    }
    if sy == 0 || sy == 3 || sy == 6 {
        return hash01(gx * 7 + sy, gy, salt + 3) < 0.6;
    }
    hash01(gx * 31 + sx, gy * 17 + sy, salt + 4) < 0.25
}

const PAPER: [f64; 3] = [0.93, 0.90, 0.82];
const INK: [f64; 3] = [0.08, 0.08, 0.14];

/// Albedo of `tex` at the local point `p` with local normal `n`.
pub(super) fn albedo(tex: Texture, p: DVec3, n: DVec3) -> [f64; 3] {
    match tex {
        Texture::Plain(c) => c,
        Texture::Floor => {
            let base = if checker(p.x, p.y, 0.2) {
                [0.82, 0.80, 0.74]
            } else {
                [0.30, 0.42, 0.60]
            };
            let r = (p.x * p.x + p.y * p.y).sqrt();
            if r > 2.2 {
                // Rings 0.008 wide every 0.03 near the rim.
                if lines(r, 0.03, 0.008) {
                    return [0.95, 0.55, 0.15];
                }
                return [0.15, 0.15, 0.18];
            }
            if lines(p.x, 0.05, 0.01) || lines(p.y, 0.05, 0.01) {
                return mix(base, INK, 0.85);
            }
            base
        }
        Texture::Backdrop => {
            if n.y > -0.5 {
                return [0.35, 0.35, 0.38]; // back and sides: plain
            }
            let (u, v) = (p.x, -p.z); // v grows downwards on the face
            let z = p.z;
            if z > 0.8 {
                if glyph_ink(u, v, 0.14, 10) {
                    INK
                } else {
                    PAPER
                }
            } else if z > 0.45 {
                if glyph_ink(u, v, 0.06, 20) {
                    [0.55, 0.05, 0.08]
                } else {
                    PAPER
                }
            } else if z > 0.12 {
                if glyph_ink(u, v, 0.025, 30) {
                    INK
                } else {
                    PAPER
                }
            } else if z > -0.35 {
                // Chirp: phase phi(x) with frequency 2 -> 60 cycles/unit over x in [-2.4, 2.4].
                let s = (u + 2.4) / 4.8;
                let phase = 4.8 * (2.0 * s + 0.5 * 58.0 * s * s);
                if phase.rem_euclid(1.0) < 0.5 {
                    [0.05, 0.05, 0.05]
                } else {
                    [0.98, 0.98, 0.95]
                }
            } else {
                let base = if checker(u, z, 0.1) {
                    [0.85, 0.25, 0.20]
                } else {
                    [0.95, 0.85, 0.30]
                };
                if lines(u + z, 0.035, 0.008) {
                    mix(base, INK, 0.8)
                } else {
                    base
                }
            }
        }
        Texture::SphereChecker { lon, lat, a, b } => {
            let q = p.normalize_or_zero();
            let phi = q.y.atan2(q.x) / std::f64::consts::TAU + 0.5; // [0, 1)
            let theta = q.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI; // [0, 1]
            let i = (phi * lon as f64).floor() as i64;
            let j = (theta * lat as f64).floor() as i64;
            let c = if (i + j).rem_euclid(2) == 0 { a } else { b };
            // Thin meridians: 1/8 of a cell wide, 4 per cell.
            if lines(phi * lon as f64 * 4.0, 1.0, 0.12) && (0.1..0.9).contains(&theta) {
                mix(c, INK, 0.7)
            } else {
                c
            }
        }
        Texture::Stripes { period, a, b } => {
            // Face coordinates: the two local axes orthogonal to the face normal.
            let (u, v) = if n.x.abs() > 0.5 {
                (p.y, p.z)
            } else if n.y.abs() > 0.5 {
                (p.x, p.z)
            } else {
                (p.x, p.y)
            };
            if (u + v).rem_euclid(period) < 0.5 * period {
                a
            } else {
                b
            }
        }
    }
}
