//! Exact point-triangle proximity, the narrow phase of cloth self-collision.

use crate::Vec3;

/// The point of triangle `(a, b, c)` closest to `p`, with its barycentric
/// weights `[w_a, w_b, w_c]` (non-negative, summing to 1). Degenerate
/// triangles are handled through their edges.
pub fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, [f64; 3]) {
    // Minimise |a + s (b - a) + t (c - a) - p|^2 over the triangle: solve
    // the 2x2 normal equations; if the minimiser falls outside (or the
    // triangle is degenerate), the answer lies on one of the three edges.
    let (e0, e1, r) = (b - a, c - a, a - p);
    let (a00, a01, a11) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
    let (b0, b1) = (e0.dot(&r), e1.dot(&r));
    let det = a00 * a11 - a01 * a01;
    if det > 1e-12 * a00 * a11 {
        let s = (a01 * b1 - a11 * b0) / det;
        let t = (a01 * b0 - a00 * b1) / det;
        if s >= 0.0 && t >= 0.0 && s + t <= 1.0 {
            return (a + e0 * s + e1 * t, [1.0 - s - t, s, t]);
        }
    }
    let on_segment = |p0: Vec3, p1: Vec3| {
        let e = p1 - p0;
        let len2 = e.norm_squared();
        let t = if len2 > 0.0 { ((p - p0).dot(&e) / len2).clamp(0.0, 1.0) } else { 0.0 };
        (p0 + e * t, t)
    };
    let (q_ab, t_ab) = on_segment(a, b);
    let (q_bc, t_bc) = on_segment(b, c);
    let (q_ca, t_ca) = on_segment(c, a);
    let candidates =
        [(q_ab, [1.0 - t_ab, t_ab, 0.0]), (q_bc, [0.0, 1.0 - t_bc, t_bc]), (q_ca, [t_ca, 0.0, 1.0 - t_ca])];
    // First minimum in a fixed order: ties resolve the same way every run.
    let mut best = candidates[0];
    for cand in &candidates[1..] {
        if (cand.0 - p).norm_squared() < (best.0 - p).norm_squared() {
            best = *cand;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_brute_force_sampling() {
        let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.2, 0.0), Vec3::new(0.3, 0.9, 0.1));
        let mut seed = 12345u64;
        let mut rand = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 3.0 - 1.0
        };
        for _ in 0..200 {
            let p = Vec3::new(rand(), rand(), rand());
            let (q, w) = closest_point_on_triangle(p, a, b, c);
            assert!((a * w[0] + b * w[1] + c * w[2] - q).norm() < 1e-12);
            assert!(w.iter().all(|&x| x >= -1e-12) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let n = 200;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
                    best = best.min((a + (b - a) * s + (c - a) * t - p).norm());
                }
            }
            let d = (q - p).norm();
            assert!(d <= best + 1e-12 && d >= best - 1e-2, "{d} vs sampled {best}");
        }
        // Degenerate (collinear) triangle: the closest point of its segment.
        let (q, _) = closest_point_on_triangle(Vec3::new(0.5, 1.0, 0.0), a, Vec3::x(), Vec3::x() * 2.0);
        assert!((q - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-12);
    }
}
