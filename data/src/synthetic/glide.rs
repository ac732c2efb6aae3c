//! The `glide` scene, for representations whose Gaussians follow the motion frame by
//! frame (the tracking model): movers that travel less than their own size between
//! the frames of a short multi-view video, along straight lines at constant speed, so
//! their true displacement is known for every surface point.
//!
//! The static set of `dolly` (floor grid, backdrop glyphs and chirp, comb of 0.012-wide
//! bars), and two movers apart, neither hiding the other from the arc cameras:
//! - `ball`, a checkered sphere of radius 0.3, glides from (-0.9, -0.2, 0.8) by
//!   (0.6, 0.1, 0.1) over the sequence, turning a quarter turn about z: 0.06 units a
//!   frame over 10 frames, a fifth of its radius;
//! - `crate`, a box of half-size 0.25 with stripes 0.2 apart (5 px at 96 px wide),
//!   glides from (1.0, 0.4, 0.45) by
//!   (-0.6, -0.2, 0), turning an eighth of a turn.

use glam::{DQuat, DVec3};

use super::scene::{Motion, Object, Path, Scene, Shape, Texture};
use super::{lit, static_set};

/// Builds the `glide` scene (see the module doc).
pub fn glide() -> Scene {
    let mut objects = static_set();
    objects.push(Object {
        name: "ball",
        shape: Shape::Sphere(0.3),
        motion: Motion {
            base: DVec3::new(-0.9, -0.2, 0.8),
            path: Path::Line(DVec3::new(0.6, 0.1, 0.1)),
            axis: DVec3::Z,
            turns: 0.25,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::SphereChecker {
            lon: 12,
            lat: 6,
            a: [0.95, 0.78, 0.10],
            b: [0.10, 0.25, 0.70],
        },
    });
    objects.push(Object {
        name: "crate",
        shape: Shape::Box(DVec3::splat(0.25)),
        motion: Motion {
            base: DVec3::new(1.0, 0.4, 0.45),
            path: Path::Line(DVec3::new(-0.6, -0.2, 0.0)),
            axis: DVec3::Z,
            turns: 0.125,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::Stripes {
            period: 0.2,
            a: [0.10, 0.55, 0.30],
            b: [0.92, 0.92, 0.88],
        },
    });
    lit(objects)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_movers_travel_under_their_size_per_frame_of_ten() {
        let scene = glide();
        assert_eq!(scene.moving(), ["ball", "crate"]);
        for (o, size) in scene.objects.iter().rev().take(2).zip([0.25, 0.3]) {
            let step = (o.motion.pose(0.1).pos - o.motion.pose(0.0).pos).length();
            assert!(step < size, "{}: {step} a frame", o.name);
        }
    }
}
