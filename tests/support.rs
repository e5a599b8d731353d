//! Helpers shared by the workspace-level tests.

use cloth_collide::closest_point_on_triangle;
use cloth_core::scene::{RunConfig, Scene};
use cloth_core::{ClothModel, Simulation, Vec3};
use std::path::PathBuf;

/// Path of a fixture scene.
pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes").join(name)
}

/// Loads a fixture scene with overrides and builds its model.
pub fn load(name: &str, overrides: &[&str]) -> (ClothModel, RunConfig) {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    let scene = Scene::parse_file(&fixture(name), &o).unwrap_or_else(|e| panic!("{e}"));
    scene.build().unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// A simulation of a fixture scene.
pub fn simulation(name: &str, overrides: &[&str]) -> (Simulation, RunConfig) {
    let (model, cfg) = load(name, overrides);
    (cfg.simulation(model), cfg)
}

/// Slope of the least-squares line through `(x, y)` points.
pub fn least_squares_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

/// Bitwise equality of two position or velocity arrays.
pub fn same_bits(a: &[Vec3], b: &[Vec3]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| p.iter().zip(q.iter()).all(|(x, y)| x.to_bits() == y.to_bits()))
}

/// xorshift64*: deterministic pseudo-random numbers in [-1, 1).
pub struct Rng(pub u64);

impl Rng {
    /// Next number in [-1, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let bits = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
        bits as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    /// A vector with components in [-1, 1).
    pub fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.uniform(), self.uniform(), self.uniform())
    }
}

/// Closest pair of particles not sharing a link, m (brute force).
pub fn min_unlinked_distance(model: &ClothModel, x: &[Vec3]) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..x.len() {
        for j in i + 1..x.len() {
            if model.incidence(i).iter().all(|inc| inc.other as usize != j) {
                best = best.min((x[i] - x[j]).norm());
            }
        }
    }
    best
}

/// Closest particle to a triangle that neither contains it nor has a
/// corner linked to it, m: exact below `REACH` (a triangle is found
/// through the cells of a 2 cm grid its box touches), `REACH` when nothing
/// is nearer.
pub fn min_unlinked_point_triangle(model: &ClothModel, x: &[Vec3]) -> f64 {
    const REACH: f64 = 0.02;
    let cell = |p: Vec3| [p.x, p.y, p.z].map(|c| (c / REACH).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = std::collections::HashMap::new();
    for (t, tri) in model.triangles().iter().enumerate() {
        let corners = tri.map(|k| x[k as usize]);
        let lo = cell(corners.iter().fold(corners[0], |m, p| m.inf(p)));
        let hi = cell(corners.iter().fold(corners[0], |m, p| m.sup(p)));
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    grid.entry([i, j, k]).or_default().push(t);
                }
            }
        }
    }
    let linked = |a: usize, b: usize| a == b || model.never_repel(a, b);
    let mut best = REACH;
    for (p, xp) in x.iter().enumerate() {
        let c = cell(*xp);
        for d in 0..27i64 {
            let key = [c[0] + d % 3 - 1, c[1] + (d / 3) % 3 - 1, c[2] + d / 9 - 1];
            for &t in grid.get(&key).into_iter().flatten() {
                let tri = model.triangles()[t];
                if tri.iter().any(|&q| linked(p, q as usize)) {
                    continue;
                }
                let [a, b, c] = tri.map(|k| x[k as usize]);
                best = best.min((closest_point_on_triangle(*xp, a, b, c).0 - xp).norm());
            }
        }
    }
    best
}

/// [`min_unlinked_point_triangle`] by brute force, for its test.
pub fn min_unlinked_point_triangle_brute(model: &ClothModel, x: &[Vec3]) -> f64 {
    let linked = |a: usize, b: usize| a == b || model.never_repel(a, b);
    let mut best = f64::INFINITY;
    for (p, xp) in x.iter().enumerate() {
        for tri in model.triangles() {
            if tri.iter().any(|&c| linked(p, c as usize)) {
                continue;
            }
            let [a, b, c] = tri.map(|k| x[k as usize]);
            best = best.min((closest_point_on_triangle(*xp, a, b, c).0 - xp).norm());
        }
    }
    best
}

pub use cloth_core::testing::reference::settle;
