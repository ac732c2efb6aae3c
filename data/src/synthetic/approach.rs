//! The `approach` scene for the multi-view video rig: movers whose distance to the
//! cameras changes several-fold, so their screen-space sampling rate `f / d(t)` changes
//! as much over time as it does across cameras (the setting where a motion-aware 3D
//! filter should differ from a static one).
//!
//! Static: the floor (0.01-wide grid lines every 0.05), the backdrop (glyphs down to
//! 0.025 tall, a 2-to-60 cycles-per-unit chirp) and the comb of 0.012-wide bars, shared
//! with `dolly`. Moving, for the arc cameras 4 units from (0, 0, 0.6):
//! - `flyer`, a sphere of radius 0.25 with a 20 x 10 checker and thin meridians, flies
//!   from (0.4, 2.0, 1.0) near the backdrop to (0.1, -2.3, 1.2): about 5.9 units from
//!   `cam00` at t = 0 and 1.65 at t = 1 (3.6x);
//! - `retreater`, a box of half-size 0.2 with 0.04-period stripes, spinning once, goes
//!   the other way, from (-0.5, -2.2, 0.85) to (-0.9, 2.0, 0.5): 1.9 units from `cam00`
//!   to 6.0 (3.1x);
//! - `propeller bar` x 2, 0.016-wide bars 0.9 long spinning two turns about a fixed hub:
//!   sub-pixel moving lines at 1/4 scale.

use glam::{DQuat, DVec3};

use super::scene::{Motion, Object, Path, Scene, Shape, Texture};
use super::{lit, propeller, static_set};

/// Builds the `approach` scene (see the module doc).
pub fn approach() -> Scene {
    let mut objects = static_set();
    objects.push(Object {
        name: "flyer",
        shape: Shape::Sphere(0.25),
        motion: Motion {
            base: DVec3::new(0.4, 2.0, 1.0),
            path: Path::Line(DVec3::new(-0.3, -4.3, 0.2)),
            axis: DVec3::Z,
            turns: 0.5,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::SphereChecker {
            lon: 20,
            lat: 10,
            a: [0.95, 0.78, 0.10],
            b: [0.10, 0.25, 0.70],
        },
    });
    objects.push(Object {
        name: "retreater",
        shape: Shape::Box(DVec3::splat(0.2)),
        motion: Motion {
            base: DVec3::new(-0.5, -2.2, 0.85),
            path: Path::Line(DVec3::new(-0.4, 4.2, -0.35)),
            axis: DVec3::Z,
            turns: 1.0,
            phase: 0.2,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::Stripes {
            period: 0.04,
            a: [0.10, 0.55, 0.30],
            b: [0.92, 0.92, 0.88],
        },
    });
    objects.extend(propeller(DVec3::new(1.0, -0.2, 0.9)));
    lit(objects)
}
