//! The analytic dynamic scene: rigidly moving spheres, boxes and a disk with procedural,
//! high-frequency textures, and exact ray casting against them.
//!
//! World axes follow Blender/D-NeRF: z up, the floor is the plane z = 0. Every object is
//! a shape in its own local frame placed by a rigid pose `x_world = R(t) x_local + p(t)`,
//! and its texture is a function of the *local* point, so a surface point keeps its
//! colour as it moves: that is what makes the forward flow exact.

use glam::{DMat3, DQuat, DVec3};

/// Geometry in an object's local frame.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// Sphere of the given radius centred on the local origin.
    Sphere(f64),
    /// Box with the given half extents centred on the local origin.
    Box(DVec3),
    /// Two-sided disk of the given radius in the local plane z = 0.
    Disk(f64),
}

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

/// A path added to an object's base position.
#[derive(Clone, Copy, Debug)]
pub enum Path {
    /// No translation.
    Still,
    /// `delta * t` (constant velocity from `base` to `base + delta`).
    Line(DVec3),
    /// Bouncing: `z += height |sin(pi bounces t)|`.
    Bounce {
        /// Apex height above the base.
        height: f64,
        /// Number of bounces over `t in [0, 1]`.
        bounces: f64,
    },
}

/// Rigid motion: `R(t) = rot(axis, phase + 2 pi turns t) * rest`, `p(t) = base + path(t)`.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    /// Position at t = 0 (before the path).
    pub base: DVec3,
    /// Translation over time.
    pub path: Path,
    /// Spin axis (world, unit).
    pub axis: DVec3,
    /// Spin turns over `t in [0, 1]`.
    pub turns: f64,
    /// Spin angle at t = 0, radians.
    pub phase: f64,
    /// Fixed orientation applied before the spin.
    pub rest: DQuat,
}

impl Motion {
    /// A static placement.
    pub fn fixed(base: DVec3, rest: DQuat) -> Self {
        Motion {
            base,
            path: Path::Still,
            axis: DVec3::Z,
            turns: 0.0,
            phase: 0.0,
            rest,
        }
    }

    /// Whether the pose depends on time.
    pub fn is_static(&self) -> bool {
        matches!(self.path, Path::Still) && self.turns == 0.0
    }

    /// The pose `(R, p)` at time `t`.
    pub fn pose(&self, t: f64) -> Pose {
        let angle = self.phase + std::f64::consts::TAU * self.turns * t;
        let q = DQuat::from_axis_angle(self.axis, angle) * self.rest;
        let offset = match self.path {
            Path::Still => DVec3::ZERO,
            Path::Line(d) => d * t,
            Path::Bounce { height, bounces } => {
                DVec3::Z * height * (std::f64::consts::PI * bounces * t).sin().abs()
            }
        };
        let rot = DMat3::from_quat(q);
        Pose {
            rot,
            rot_t: rot.transpose(),
            pos: self.base + offset,
        }
    }
}

/// A rigid pose: `x_world = rot x_local + pos`.
#[derive(Clone, Copy, Debug)]
pub struct Pose {
    /// Rotation local to world.
    pub rot: DMat3,
    /// Its transpose (world to local).
    pub rot_t: DMat3,
    /// Translation.
    pub pos: DVec3,
}

impl Pose {
    /// Local point to world.
    pub fn to_world(&self, p: DVec3) -> DVec3 {
        self.rot * p + self.pos
    }
}

/// One object of the scene.
#[derive(Clone, Copy, Debug)]
pub struct Object {
    /// Short name (for reports).
    pub name: &'static str,
    /// Local geometry.
    pub shape: Shape,
    /// Placement over time.
    pub motion: Motion,
    /// Surface colour as a function of the local point.
    pub texture: Texture,
}

/// A ray-surface intersection.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Index of the object hit.
    pub object: usize,
    /// Ray parameter (distance along the unit direction).
    pub dist: f64,
    /// Hit point in the object's local frame.
    pub local: DVec3,
    /// Outward normal in the local frame (facing the ray for the two-sided disk).
    pub normal: DVec3,
}

/// A scene: objects plus a directional light.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The objects.
    pub objects: Vec<Object>,
    /// Unit direction towards the light (world).
    pub light: DVec3,
}

/// Per-camera-origin precomputation for [`Posed::trace_from`].
#[derive(Clone, Debug)]
pub struct Origin {
    /// Ray origin (world).
    pub o: DVec3,
    /// The origin in each object's local frame.
    pub o_local: Vec<DVec3>,
    /// Bounding-sphere centre minus origin, per object.
    pub oc: Vec<DVec3>,
    /// `|oc|^2 - r^2` per object.
    pub oc2_minus_r2: Vec<f64>,
    /// Bounding-sphere radius per object.
    pub radius: Vec<f64>,
}

/// The scene posed at one time: every object's pose, ready for ray casting.
#[derive(Clone, Debug)]
pub struct Posed<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Time.
    pub t: f64,
    /// Pose of each object.
    pub poses: Vec<Pose>,
}

impl Scene {
    /// Poses every object at time `t`.
    pub fn at(&self, t: f64) -> Posed<'_> {
        Posed {
            scene: self,
            t,
            poses: self.objects.iter().map(|o| o.motion.pose(t)).collect(),
        }
    }

    /// Names of the objects that move.
    pub fn moving(&self) -> Vec<&'static str> {
        self.objects
            .iter()
            .filter(|o| !o.motion.is_static())
            .map(|o| o.name)
            .collect()
    }
}

impl Posed<'_> {
    /// World-space bounding sphere `(centre, radius)` of object `i`.
    pub fn bounding_sphere(&self, i: usize) -> (DVec3, f64) {
        let r = match self.scene.objects[i].shape {
            Shape::Sphere(r) | Shape::Disk(r) => r,
            Shape::Box(h) => h.length(),
        };
        (self.poses[i].pos, r)
    }

    /// World-space corners of a box enclosing object `i` (8 points), for screen bounds.
    pub fn corners(&self, i: usize) -> [DVec3; 8] {
        let h = match self.scene.objects[i].shape {
            Shape::Sphere(r) => DVec3::splat(r),
            Shape::Box(h) => h,
            Shape::Disk(r) => DVec3::new(r, r, 0.0),
        };
        let pose = &self.poses[i];
        let mut out = [DVec3::ZERO; 8];
        for (k, c) in out.iter_mut().enumerate() {
            let s = DVec3::new(
                if k & 1 == 0 { -1.0 } else { 1.0 },
                if k & 2 == 0 { -1.0 } else { 1.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            );
            *c = pose.to_world(s * h);
        }
        out
    }

    /// Nearest hit of the ray `o + s d` (`d` unit, `s > 1e-9`) among the objects listed
    /// in `candidates`.
    pub fn trace(&self, o: DVec3, d: DVec3, candidates: &[u16]) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for &ci in candidates {
            let i = ci as usize;
            let pose = &self.poses[i];
            let lo = pose.rot_t * (o - pose.pos);
            let ld = pose.rot_t * d;
            let limit = best.map_or(f64::INFINITY, |h| h.dist);
            if let Some((dist, local, normal)) =
                intersect(self.scene.objects[i].shape, lo, ld, limit)
            {
                best = Some(Hit {
                    object: i,
                    dist,
                    local,
                    normal,
                });
            }
        }
        best
    }

    /// Precomputes, for rays that all start at `o` (one camera), each object's local
    /// origin and its bounding sphere relative to `o`.
    pub fn from_origin(&self, o: DVec3) -> Origin {
        let n = self.poses.len();
        let mut o_local = Vec::with_capacity(n);
        let mut oc = Vec::with_capacity(n);
        let mut oc2_minus_r2 = Vec::with_capacity(n);
        let mut radius = Vec::with_capacity(n);
        for i in 0..n {
            let pose = &self.poses[i];
            o_local.push(pose.rot_t * (o - pose.pos));
            let (c, r) = self.bounding_sphere(i);
            let v = c - o;
            oc.push(v);
            oc2_minus_r2.push(v.length_squared() - r * r);
            radius.push(r);
        }
        Origin {
            o,
            o_local,
            oc,
            oc2_minus_r2,
            radius,
        }
    }

    /// Same as [`Posed::trace`] for a ray from the precomputed origin, rejecting objects
    /// by their bounding sphere first (`|oc|^2 - (oc . d)^2 > r^2` misses; so does a
    /// sphere entirely behind the origin or farther than the best hit so far).
    pub fn trace_from(&self, org: &Origin, d: DVec3, candidates: &[u16]) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for &ci in candidates {
            let i = ci as usize;
            let b = org.oc[i].dot(d);
            let r = org.radius[i];
            let limit = best.map_or(f64::INFINITY, |h| h.dist);
            if b + r < 0.0 || b - r > limit || org.oc2_minus_r2[i] - b * b > 0.0 {
                continue;
            }
            let ld = self.poses[i].rot_t * d;
            if let Some((dist, local, normal)) =
                intersect(self.scene.objects[i].shape, org.o_local[i], ld, limit)
            {
                best = Some(Hit {
                    object: i,
                    dist,
                    local,
                    normal,
                });
            }
        }
        best
    }

    /// Nearest hit among all objects.
    pub fn trace_all(&self, o: DVec3, d: DVec3) -> Option<Hit> {
        let all: Vec<u16> = (0..self.poses.len() as u16).collect();
        self.trace(o, d, &all)
    }

    /// Shaded colour of a hit: `albedo (0.45 + 0.55 max(0, n . l))`, view-independent.
    pub fn shade(&self, hit: &Hit) -> [f64; 3] {
        let obj = &self.scene.objects[hit.object];
        let albedo = texture(obj.texture, hit.local, hit.normal);
        let n = self.poses[hit.object].rot * hit.normal;
        let k = 0.45 + 0.55 * n.dot(self.scene.light).max(0.0);
        [albedo[0] * k, albedo[1] * k, albedo[2] * k]
    }
}

/// Ray-shape intersection in local coordinates: returns `(s, point, normal)` for the
/// nearest `1e-9 < s < limit`.
fn intersect(shape: Shape, o: DVec3, d: DVec3, limit: f64) -> Option<(f64, DVec3, DVec3)> {
    const EPS: f64 = 1e-9;
    match shape {
        Shape::Sphere(r) => {
            // |o + s d|^2 = r^2 with |d| = 1: s^2 + 2 b s + c = 0.
            let b = o.dot(d);
            let c = o.length_squared() - r * r;
            let disc = b * b - c;
            if disc < 0.0 {
                return None;
            }
            let q = disc.sqrt();
            let s = if -b - q > EPS { -b - q } else { -b + q };
            if s <= EPS || s >= limit {
                return None;
            }
            let p = o + s * d;
            Some((s, p, p / r))
        }
        Shape::Box(h) => {
            // Slab method.
            let inv = d.recip();
            let t0 = (-h - o) * inv;
            let t1 = (h - o) * inv;
            let tmin = t0.min(t1);
            let tmax = t0.max(t1);
            let near = tmin.max_element();
            let far = tmax.min_element();
            if near > far || far <= EPS {
                return None;
            }
            let s = if near > EPS { near } else { far };
            if s >= limit {
                return None;
            }
            let p = o + s * d;
            // Normal: the axis whose face the point is on (largest relative coordinate).
            let rel = (p / h).abs();
            let n = if rel.x >= rel.y && rel.x >= rel.z {
                DVec3::X * p.x.signum()
            } else if rel.y >= rel.z {
                DVec3::Y * p.y.signum()
            } else {
                DVec3::Z * p.z.signum()
            };
            Some((s, p, n))
        }
        Shape::Disk(r) => {
            if d.z.abs() < 1e-12 {
                return None;
            }
            let s = -o.z / d.z;
            if s <= EPS || s >= limit {
                return None;
            }
            let p = o + s * d;
            if p.x * p.x + p.y * p.y > r * r {
                return None;
            }
            let n = if d.z < 0.0 { DVec3::Z } else { -DVec3::Z };
            Some((s, DVec3::new(p.x, p.y, 0.0), n))
        }
    }
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

fn texture(tex: Texture, p: DVec3, n: DVec3) -> [f64; 3] {
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
