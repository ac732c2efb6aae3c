//! The `plunge` scene of the stability suite: the motions that break
//! anti-aliasing, for the multi-view rig.
//!
//! The static set of `dolly` (floor grid, backdrop glyphs and chirp, comb of 0.012-wide
//! bars), and three movers, for the arc cameras 4 units from (0, 0, 0.6):
//! - `diver`, a checkered sphere of radius 0.2, waits near the backdrop, 5.9 units from
//!   `cam00`, dives to 1.2 units during `t in [0.45, 0.55]` and stays there: its `f / d`
//!   changes 4.8x within a tenth of the sequence;
//! - `slider`, a bar 0.01 wide and 0.8 tall crossing 1.2 units sideways over the
//!   sequence: about 0.6 px per frame at 128 px wide and 60 frames, narrower than a
//!   pixel and moving less than one;
//! - the shared propeller (two 0.016-wide bars spinning two turns).

use glam::{DQuat, DVec3};

use super::scene::{Motion, Object, Path, Scene, Shape, Texture};
use super::{lit, propeller, static_set};

/// Builds the `plunge` scene (see the module doc).
pub fn plunge() -> Scene {
    let mut objects = static_set();
    objects.push(Object {
        name: "diver",
        shape: Shape::Sphere(0.2),
        motion: Motion {
            base: DVec3::new(0.35, 2.0, 1.0),
            path: Path::Dash {
                delta: DVec3::new(-0.3, -4.7, 0.3),
                start: 0.45,
                end: 0.55,
            },
            axis: DVec3::Z,
            turns: 0.25,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::SphereChecker {
            lon: 16,
            lat: 8,
            a: [0.95, 0.55, 0.10],
            b: [0.15, 0.15, 0.55],
        },
    });
    objects.push(Object {
        name: "slider",
        shape: Shape::Box(DVec3::new(0.005, 0.005, 0.4)),
        motion: Motion {
            base: DVec3::new(-0.9, -0.8, 0.5),
            path: Path::Line(DVec3::new(1.2, 0.0, 0.0)),
            axis: DVec3::Z,
            turns: 0.0,
            phase: 0.0,
            rest: DQuat::IDENTITY,
        },
        texture: Texture::Plain([0.85, 0.10, 0.10]),
    });
    objects.extend(propeller(DVec3::new(1.0, -0.2, 0.9)));
    lit(objects)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::rig::arc_positions;

    #[test]
    fn the_diver_closes_in_about_five_times_within_a_tenth_of_the_sequence() {
        let scene = plunge();
        let cam = arc_positions(16)[0];
        let diver = scene
            .objects
            .iter()
            .position(|o| o.name == "diver")
            .expect("diver");
        let dist = |t: f64| (scene.objects[diver].motion.pose(t).pos - cam).length();
        let (far, near) = (dist(0.45), dist(0.55));
        assert!((dist(0.0) - far).abs() < 1e-12, "waits before the dash");
        assert!((dist(1.0) - near).abs() < 1e-12, "stays after the dash");
        assert!(far / near > 4.5 && far / near < 5.5, "{far} / {near}");
        let mid = dist(0.5);
        assert!(mid < far && mid > near);
    }
}
