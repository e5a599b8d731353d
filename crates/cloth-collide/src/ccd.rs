//! Continuous collision detection between moving triangles: the first
//! time in a step at which a point meets a triangle or an edge meets an
//! edge, every vertex moving on a straight line (Provot 1997, "Collision
//! and self-collision handling in cloth model dedicated to design
//! garments"; Bridson, Fedkiw & Anderson 2002 §4).
//!
//! Four points can only meet when they are coplanar, so the candidate
//! times are the roots in `[0, 1]` of the cubic `f(t) = (x_b - x_a) x
//! (x_c - x_a) . (x_d - x_a)`; at each, in order, the pair is tested for
//! proximity. A pair that stays coplanar (a flat sheet moving in its own
//! plane) is tested where `f` is within round-off of zero. A pair whose
//! start distance exceeds the largest relative displacement of its
//! vertices cannot meet and is ruled out before the cubic.

use crate::Vec3;
use crate::closest_point_on_triangle;

/// A vertex's position at the start and at the end of the step, m.
pub type Path = [Vec3; 2];

/// Earliest fraction `t` of the step (in `[0, 1]`) at which point `p`
/// comes within `eta` (m) of triangle `(a, b, c)`, or `None`.
pub fn point_triangle_impact(p: Path, a: Path, b: Path, c: Path, eta: f64) -> Option<f64> {
    // Most pairs are ruled out at once: the gap closes by at most the
    // largest relative displacement of the point and a corner.
    let moved = |x: Path| x[1] - x[0];
    let closing = [a, b, c].iter().map(|&x| (moved(p) - moved(x)).norm()).fold(0.0, f64::max);
    let (q, _) = closest_point_on_triangle(p[0], a[0], b[0], c[0]);
    if (p[0] - q).norm() - closing >= eta {
        return None;
    }
    first_meeting([p, a, b, c], eta, |[p, a, b, c]| {
        let (q, _) = closest_point_on_triangle(p, a, b, c);
        (p - q).norm()
    })
}

/// Earliest fraction `t` of the step at which segment `(p, q)` comes
/// within `eta` (m) of segment `(r, s)`, or `None`.
pub fn edge_edge_impact(p: Path, q: Path, r: Path, s: Path, eta: f64) -> Option<f64> {
    // As for a point: the gap closes by at most the largest relative
    // displacement of an end of one edge and an end of the other.
    let moved = |x: Path| x[1] - x[0];
    let closing = [p, q].iter().flat_map(|&x| [r, s].map(|y| (moved(x) - moved(y)).norm())).fold(0.0, f64::max);
    if segment_distance(p[0], q[0], r[0], s[0]) - closing >= eta {
        return None;
    }
    first_meeting([p, q, r, s], eta, |[p, q, r, s]| segment_distance(p, q, r, s))
}

/// The first candidate time at which `distance` of the four points at that
/// time is below `eta`.
fn first_meeting(paths: [Path; 4], eta: f64, distance: impl Fn([Vec3; 4]) -> f64) -> Option<f64> {
    let at = |t: f64| paths.map(|[x0, x1]| x0 + (x1 - x0) * t);
    coplanar_times(&paths, eta).into_iter().flatten().find(|&t| distance(at(t)) < eta)
}

/// Up to five times in `[0, 1]`, ascending, at which the four points are
/// coplanar (roots of the cubic, found by bisection between its turning
/// points) or within `eta` times their size squared of it (grazing and
/// flat pairs).
fn coplanar_times(paths: &[Path; 4], eta: f64) -> [Option<f64>; 5] {
    let origin = paths[0];
    let [p, v] = [0, 1].map(|k| [1, 2, 3].map(|i| paths[i][k] - origin[k]));
    // Velocities over the step (positions at t = 1 minus at t = 0).
    let v = [0, 1, 2].map(|i| v[i] - p[i]);
    let triple = |a: Vec3, b: Vec3, c: Vec3| a.cross(&b).dot(&c);
    let d = triple(p[0], p[1], p[2]);
    let c = triple(v[0], p[1], p[2]) + triple(p[0], v[1], p[2]) + triple(p[0], p[1], v[2]);
    let b = triple(p[0], v[1], v[2]) + triple(v[0], p[1], v[2]) + triple(v[0], v[1], p[2]);
    let a = triple(v[0], v[1], v[2]);
    let f = |t: f64| ((a * t + b) * t + c) * t + d;
    let size = p.iter().chain(&[p[0] + v[0], p[1] + v[1], p[2] + v[2]]).map(|x| x.norm()).fold(0.0, f64::max);
    let flat = eta * size * size;
    // Turning points of f split [0, 1] into pieces on which it is monotone.
    let mut cuts = [0.0, 1.0, 1.0, 1.0];
    let (qa, qb, qc) = (3.0 * a, 2.0 * b, c);
    let mut n = 1;
    let mut cut = |t: f64| {
        if t > 0.0 && t < 1.0 {
            cuts[n] = t;
            n += 1;
        }
    };
    if qa.abs() > 1e-300 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let root = disc.sqrt();
            let (t1, t2) = ((-qb - root) / (2.0 * qa), (-qb + root) / (2.0 * qa));
            cut(t1.min(t2));
            cut(t1.max(t2));
        }
    } else if qb.abs() > 1e-300 {
        cut(-qc / qb);
    }
    cuts[n] = 1.0;
    let mut times = [None; 5];
    let mut found = 0;
    let mut push = |t: f64| {
        if found < times.len() && times[..found].iter().all(|&s| s != Some(t)) {
            times[found] = Some(t);
            found += 1;
        }
    };
    for piece in cuts[..=n].windows(2) {
        let (mut lo, mut hi) = (piece[0], piece[1]);
        let (f_lo, f_hi) = (f(lo), f(hi));
        if f_lo.abs() <= flat {
            push(lo);
        } else if f_lo * f_hi < 0.0 {
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if f(mid) * f_lo > 0.0 { lo = mid } else { hi = mid }
            }
            push(hi);
        }
    }
    if f(1.0).abs() <= flat {
        push(1.0);
    }
    times
}

/// Whether segment `(p, q)` passes through the inside of triangle
/// `(a, b, c)`: its ends on strictly opposite sides of the plane, and the
/// crossing point inside the triangle. A segment in the plane or ending on
/// it does not count.
pub fn segment_crosses_triangle(p: Vec3, q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let normal = (b - a).cross(&(c - a));
    let (dp, dq) = ((p - a).dot(&normal), (q - a).dot(&normal));
    // Not strictly opposite sides (NaN included): no crossing.
    if dp * dq >= 0.0 || (dp * dq).is_nan() {
        return false;
    }
    let x = p + (q - p) * (dp / (dp - dq));
    // Inside: x on the inner side of the three edges.
    let side = |u: Vec3, v: Vec3| (v - u).cross(&(x - u)).dot(&normal) > 0.0;
    side(a, b) && side(b, c) && side(c, a)
}

/// Distance between segments `(p, q)` and `(r, s)`, m.
pub fn segment_distance(p: Vec3, q: Vec3, r: Vec3, s: Vec3) -> f64 {
    let (d1, d2, w) = (q - p, s - r, p - r);
    let (a, e, f) = (d1.dot(&d1), d2.dot(&d2), d2.dot(&w));
    let on = |x: f64| x.clamp(0.0, 1.0);
    let (u, v) = if a <= 1e-300 && e <= 1e-300 {
        (0.0, 0.0)
    } else if a <= 1e-300 {
        (0.0, on(f / e))
    } else {
        let c = d1.dot(&w);
        if e <= 1e-300 {
            (on(-c / a), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let u = if denom > 1e-14 * a * e { on((b * f - c * e) / denom) } else { 0.0 };
            let v = (b * u + f) / e;
            // Clamp v, then recompute u for the clamped v.
            if v < 0.0 {
                (on(-c / a), 0.0)
            } else if v > 1.0 {
                (on((b - c) / a), 1.0)
            } else {
                (u, v)
            }
        }
    };
    (p + d1 * u - (r + d2 * v)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn still(x: Vec3) -> Path {
        [x, x]
    }

    /// A point falling through the middle of a triangle meets it when it
    /// reaches the plane; one passing beside it does not.
    #[test]
    fn a_point_through_a_triangle_meets_it_on_the_plane() {
        let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        let through = [Vec3::new(0.2, 0.2, 0.3), Vec3::new(0.2, 0.2, -0.1)];
        let t = point_triangle_impact(through, still(a), still(b), still(c), 1e-9).unwrap();
        assert!((t - 0.75).abs() < 1e-12, "{t}");
        let beside = [Vec3::new(0.8, 0.8, 0.3), Vec3::new(0.8, 0.8, -0.1)];
        assert_eq!(point_triangle_impact(beside, still(a), still(b), still(c), 1e-9), None);
        let short = [Vec3::new(0.2, 0.2, 0.3), Vec3::new(0.2, 0.2, 0.01)];
        assert_eq!(point_triangle_impact(short, still(a), still(b), still(c), 1e-9), None);
    }

    /// A triangle that turns through a still point: the meeting time is
    /// where the point is on the moving plane, found to round-off.
    #[test]
    fn a_turning_triangle_meets_a_still_point() {
        let p = still(Vec3::new(0.3, 0.3, 0.1));
        // The triangle's far corner c rises from z = -0.5 to z = 0.5.
        let (a, b) = (still(Vec3::new(0.0, 0.0, 0.0)), still(Vec3::new(1.0, 0.0, 0.0)));
        let c = [Vec3::new(0.0, 1.0, -0.5), Vec3::new(0.0, 1.0, 0.5)];
        let t = point_triangle_impact(p, a, b, c, 1e-9).unwrap();
        // On the plane through a, b, c(t): z = y c_z(t) = 0.3 (t - 0.5) = 0.1.
        assert!((t - (0.1 / 0.3 + 0.5)).abs() < 1e-12, "{t}");
    }

    /// Two edges crossing like the bars of an X meet; skew ones that pass
    /// above each other do not.
    #[test]
    fn crossing_edges_meet_and_passing_ones_do_not() {
        let (r, s) = (still(Vec3::new(-1.0, 0.0, 0.0)), still(Vec3::new(1.0, 0.0, 0.0)));
        let p = [Vec3::new(0.0, -1.0, 0.2), Vec3::new(0.0, -1.0, -0.2)];
        let q = [Vec3::new(0.0, 1.0, 0.2), Vec3::new(0.0, 1.0, -0.2)];
        let t = edge_edge_impact(p, q, r, s, 1e-9).unwrap();
        assert!((t - 0.5).abs() < 1e-12, "{t}");
        let p = [Vec3::new(2.0, -1.0, 0.2), Vec3::new(2.0, -1.0, -0.2)];
        let q = [Vec3::new(2.0, 1.0, 0.2), Vec3::new(2.0, 1.0, -0.2)];
        assert_eq!(edge_edge_impact(p, q, r, s, 1e-9), None);
    }

    /// A flat sheet's point moving in the sheet's plane is coplanar with a
    /// far triangle of it all the step; it does not meet it.
    #[test]
    fn coplanar_motion_meets_only_what_it_reaches() {
        let (a, b, c) = (still(Vec3::zeros()), still(Vec3::x()), still(Vec3::y()));
        let far = [Vec3::new(2.0, 2.0, 0.0), Vec3::new(1.5, 2.0, 0.0)];
        assert_eq!(point_triangle_impact(far, a, b, c, 1e-9), None);
        let onto = [Vec3::new(2.0, 0.2, 0.0), Vec3::new(0.2, 0.2, 0.0)];
        // Found, though at the end of the step rather than where it crosses
        // the edge: every time of a flat pair is a root.
        assert_eq!(point_triangle_impact(onto, a, b, c, 1e-9), Some(1.0));
    }

    /// A segment through a triangle crosses it; one beside it, one ending
    /// on it and one lying in its plane do not.
    #[test]
    fn segments_cross_triangles_through_their_inside_only() {
        let (a, b, c) = (Vec3::zeros(), Vec3::x(), Vec3::y());
        let up = |x: f64, y: f64, z0: f64, z1: f64| (Vec3::new(x, y, z0), Vec3::new(x, y, z1));
        let (p, q) = up(0.2, 0.2, -1.0, 1.0);
        assert!(segment_crosses_triangle(p, q, a, b, c));
        let (p, q) = up(0.7, 0.7, -1.0, 1.0);
        assert!(!segment_crosses_triangle(p, q, a, b, c));
        let (p, q) = up(0.2, 0.2, 0.0, 1.0);
        assert!(!segment_crosses_triangle(p, q, a, b, c));
        assert!(!segment_crosses_triangle(Vec3::new(-1.0, 0.2, 0.0), Vec3::new(1.0, 0.2, 0.0), a, b, c));
    }

    /// The segment distance against sampling.
    #[test]
    fn segment_distance_matches_sampling() {
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..100 {
            let [p, q, r, s] = [(); 4].map(|_| Vec3::new(rand(), rand(), rand()));
            let n = 300;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                let x = p + (q - p) * (i as f64 / n as f64);
                for j in 0..=n {
                    best = best.min((x - (r + (s - r) * (j as f64 / n as f64))).norm());
                }
            }
            let d = segment_distance(p, q, r, s);
            assert!(d <= best + 1e-12 && d >= best - 1e-2, "{d} vs sampled {best}");
        }
        // Parallel segments.
        let d = segment_distance(Vec3::zeros(), Vec3::x(), Vec3::new(0.5, 1.0, 0.0), Vec3::new(1.5, 1.0, 0.0));
        assert!((d - 1.0).abs() < 1e-12);
    }
}
