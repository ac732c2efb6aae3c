//! The built-in synthetic dynamic scene behind `maaf generate`: an analytic, alias-prone
//! scene rendered with supersampled ray casting and written in D-NeRF format.
//!
//! The default scene, `dolly`, is built to test anti-aliasing across zoom levels:
//! - a static textured floor disk (checker, 0.01-wide grid lines every 0.05, fine rings)
//!   and backdrop (text-like glyphs at three sizes down to 0.025 units tall, a square-wave
//!   chirp from 2 to 60 cycles per unit, fine diagonal stripes), seen at grazing angles;
//! - a static comb of 9 bars 0.012 wide (about 1 pixel at 200x200);
//! - a checkered sphere that flies from behind the scene (about 5.8 units from the front
//!   cameras) to just in front of them (about 1.9 units): f/d changes about 3x;
//! - a tilted striped box spinning, a propeller of two thin bars, a bouncing striped ball.
//!
//! The `approach` scene ([`approach`]) is built for the multi-view rig
//! ([`multiview`]): the same static set, with movers whose distance to the cameras
//! changes 3 to 4 times over the sequence. The `plunge` scene ([`plunge`]) is the
//! stability suite's: a mover whose distance changes 4.8x within a tenth of the
//! sequence, and bars thinner than a pixel moving less than a pixel per frame. The
//! `glide` scene ([`glide`]) is the tracking model's: movers that travel less than
//! their size between frames of a short video, at constant velocity.
//!
//! Cameras sit on a spherical cap 4 units from the target (0, 0, 0.6), azimuth within
//! 60 degrees of the front (-y), elevation 12 to 50 degrees, field of view 50 degrees.

pub mod approach;
pub mod dynamic3dgs;
pub mod glide;
pub mod multiview;
pub mod plunge;
pub mod points;
pub mod render;
pub mod rig;
pub mod scene;
pub mod write;

use glam::{DQuat, DVec3};

use self::scene::{Motion, Object, Path, Scene, Shape, Texture};
use super::bounds::Aabb;
use super::error::DataError;

pub use dynamic3dgs::generate_dynamic3dgs;
pub use multiview::{MultiviewOptions, generate_multiview};
pub use write::{GenerateOptions, GenerateSummary, Rig, generate};

/// Names of the built-in scenes (`--scene`).
pub const SCENES: &[&str] = &["dolly", "approach", "plunge", "glide"];

/// The default scene name.
pub const DEFAULT_SCENE: &str = "dolly";

/// Builds a built-in scene by name, or an error listing the known names.
pub fn build_scene(name: &str) -> Result<Scene, DataError> {
    match name {
        "dolly" => Ok(dolly()),
        "approach" => Ok(approach::approach()),
        "plunge" => Ok(plunge::plunge()),
        "glide" => Ok(glide::glide()),
        _ => Err(DataError::Request {
            path: "--scene".into(),
            message: format!(
                "unknown scene {name:?}; built-in scenes: {}",
                SCENES.join(", ")
            ),
        }),
    }
}

/// World bounds of the scene over `t in [0, 1]`: the union of every object's posed
/// bounding-box corners at 101 times, padded by 0.02.
pub fn scene_bounds(scene: &Scene) -> Aabb {
    let mut min = DVec3::splat(f64::INFINITY);
    let mut max = DVec3::splat(f64::NEG_INFINITY);
    for k in 0..=100 {
        let posed = scene.at(k as f64 / 100.0);
        for i in 0..scene.objects.len() {
            for c in posed.corners(i) {
                min = min.min(c);
                max = max.max(c);
            }
        }
    }
    Aabb {
        min: min - DVec3::splat(0.02),
        max: max + DVec3::splat(0.02),
    }
}

/// The static set both scenes share: floor disk, backdrop and the comb of thin bars.
fn static_set() -> Vec<Object> {
    let fixed = |p: DVec3| Motion::fixed(p, DQuat::IDENTITY);
    let mut objects = vec![
        Object {
            name: "floor",
            shape: Shape::Disk(2.6),
            motion: fixed(DVec3::ZERO),
            texture: Texture::Floor,
        },
        Object {
            name: "backdrop",
            shape: Shape::Box(DVec3::new(2.4, 0.03, 1.3)),
            motion: fixed(DVec3::new(0.0, 2.4, 1.3)),
            texture: Texture::Backdrop,
        },
    ];
    for i in 0..9 {
        objects.push(Object {
            name: "comb bar",
            shape: Shape::Box(DVec3::new(0.006, 0.006, 0.6)),
            motion: fixed(DVec3::new(-2.0 + 0.07 * i as f64, 1.3, 0.6)),
            texture: Texture::Plain([0.55, 0.08, 0.08]),
        });
    }
    objects
}

fn dolly() -> Scene {
    let mut objects = static_set();
    objects.push(Object {
        name: "flyer",
        shape: Shape::Sphere(0.3),
        motion: Motion {
            base: DVec3::new(0.35, 2.1, 1.35),
            path: Path::Line(DVec3::new(-0.35, -4.2, -0.55)),
            axis: DVec3::Z,
            turns: 1.0,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::SphereChecker {
            lon: 16,
            lat: 8,
            a: [0.95, 0.78, 0.10],
            b: [0.10, 0.25, 0.70],
        },
    });
    objects.push(Object {
        name: "spinner",
        shape: Shape::Box(DVec3::splat(0.28)),
        motion: Motion {
            base: DVec3::new(1.05, 0.15, 0.52),
            path: Path::Still,
            axis: DVec3::Z,
            turns: 0.75,
            phase: 0.3,
            rest: DQuat::from_rotation_x(0.35),
        },
        texture: Texture::Stripes {
            period: 0.05,
            a: [0.10, 0.55, 0.30],
            b: [0.92, 0.92, 0.88],
        },
    });
    objects.extend(propeller(DVec3::new(-0.95, -0.35, 1.0)));
    objects.push(Object {
        name: "bouncer",
        shape: Shape::Sphere(0.18),
        motion: Motion {
            base: DVec3::new(-0.55, -1.05, 0.18),
            path: Path::Bounce {
                height: 0.8,
                bounces: 3.0,
            },
            axis: DVec3::X,
            turns: 1.5,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::SphereChecker {
            lon: 24,
            lat: 12,
            a: [0.85, 0.12, 0.10],
            b: [0.97, 0.97, 0.97],
        },
    });
    lit(objects)
}

/// A propeller both scenes share: two 0.016-wide bars 0.9 long, a quarter turn apart,
/// spinning two turns about the y axis through `hub`, and the small sphere at the hub.
fn propeller(hub: DVec3) -> [Object; 3] {
    let bar = |k: u32| Object {
        name: "propeller bar",
        shape: Shape::Box(DVec3::new(0.008, 0.008, 0.45)),
        motion: Motion {
            base: hub,
            path: Path::Still,
            axis: DVec3::Y,
            turns: 2.0,
            phase: k as f64 * std::f64::consts::FRAC_PI_2,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::Plain([0.10, 0.45, 0.15]),
    };
    let hub = Object {
        name: "hub",
        shape: Shape::Sphere(0.04),
        motion: Motion::fixed(hub, DQuat::IDENTITY),
        texture: Texture::Plain([0.2, 0.2, 0.2]),
    };
    [bar(0), bar(1), hub]
}

/// The scene of `objects` under the light both scenes share, from
/// `(0.4, -0.6, 0.75)` normalised (above, in front, to the right).
fn lit(objects: Vec<Object>) -> Scene {
    Scene {
        objects,
        light: DVec3::new(0.4, -0.6, 0.75).normalize(),
    }
}
