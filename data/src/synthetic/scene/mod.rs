//! The analytic dynamic scene: rigidly moving spheres, boxes and a disk with procedural,
//! high-frequency textures, and exact ray casting against them.
//!
//! World axes follow Blender/D-NeRF: z up, the floor is the plane z = 0. Every object is
//! a shape in its own local frame placed by a rigid pose `x_world = R(t) x_local + p(t)`,
//! and its texture is a function of the *local* point, so a surface point keeps its
//! colour as it moves: that is what makes the forward flow exact.

mod intersect;
mod texture;

use glam::{DMat3, DQuat, DVec3};

use self::intersect::intersect;
pub use self::texture::Texture;
pub(crate) use self::texture::hash01;

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
    /// A dash: still at `base` until `start`, `delta` at constant velocity until `end`,
    /// still at `base + delta` after: `delta * clamp((t - start) / (end - start), 0, 1)`.
    Dash {
        /// Total translation.
        delta: DVec3,
        /// Time the dash starts.
        start: f64,
        /// Time it ends (> `start`).
        end: f64,
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
            Path::Dash { delta, start, end } => {
                delta * ((t - start) / (end - start)).clamp(0.0, 1.0)
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
        self.nearest(candidates, |i, _| {
            let pose = &self.poses[i];
            Some((pose.rot_t * (o - pose.pos), pose.rot_t * d))
        })
    }

    /// The nearest hit among `candidates`: `local_ray(i, limit)` gives object `i`'s ray
    /// `(origin, direction)` in its local frame, or `None` to skip the object; `limit` is
    /// the distance of the best hit so far (infinite before the first).
    fn nearest(
        &self,
        candidates: &[u16],
        mut local_ray: impl FnMut(usize, f64) -> Option<(DVec3, DVec3)>,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for &ci in candidates {
            let i = ci as usize;
            let limit = best.map_or(f64::INFINITY, |h| h.dist);
            let Some((lo, ld)) = local_ray(i, limit) else {
                continue;
            };
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
        self.nearest(candidates, |i, limit| {
            let b = org.oc[i].dot(d);
            let r = org.radius[i];
            if b + r < 0.0 || b - r > limit || org.oc2_minus_r2[i] - b * b > 0.0 {
                return None;
            }
            Some((org.o_local[i], self.poses[i].rot_t * d))
        })
    }

    /// Nearest hit among all objects.
    pub fn trace_all(&self, o: DVec3, d: DVec3) -> Option<Hit> {
        let all: Vec<u16> = (0..self.poses.len() as u16).collect();
        self.trace(o, d, &all)
    }

    /// Shaded colour of a hit: `albedo (0.45 + 0.55 max(0, n . l))`, view-independent.
    pub fn shade(&self, hit: &Hit) -> [f64; 3] {
        let obj = &self.scene.objects[hit.object];
        let albedo = texture::albedo(obj.texture, hit.local, hit.normal);
        let n = self.poses[hit.object].rot * hit.normal;
        let k = 0.45 + 0.55 * n.dot(self.scene.light).max(0.0);
        [albedo[0] * k, albedo[1] * k, albedo[2] * k]
    }
}
