//! Exact ray casting against the local shapes of the analytic scene.

use glam::DVec3;

use super::Shape;

/// Ray-shape intersection in local coordinates: returns `(s, point, normal)` for the
/// nearest `1e-9 < s < limit`.
pub(super) fn intersect(
    shape: Shape,
    o: DVec3,
    d: DVec3,
    limit: f64,
) -> Option<(f64, DVec3, DVec3)> {
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
