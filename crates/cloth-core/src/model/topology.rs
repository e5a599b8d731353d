//! Rectangular quad-grid panels and Choi & Ko's two connection types.
//!
//! Particle `P(i, j)` (i along the panel's u axis, j along v) is linked to
//! - type 1, "sequential": `P(i+1,j)`, `P(i,j+1)`, `P(i+1,j+1)`, `P(i-1,j+1)`
//!   (structure and both shear diagonals);
//! - type 2, "interlaced": `P(i+2,j)`, `P(i,j+2)`, `P(i+2,j+2)`, `P(i-2,j+2)`.
//!
//! Interlacing matters: with sequential links only, a fold can form without
//! raising any bending energy (Choi & Ko 2002, §3.1).

use crate::FieldError;
use crate::Vec3;
use serde::{Deserialize, Serialize};

/// An edge of a grid panel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Edge {
    /// Nodes with `i = 0`.
    IMin,
    /// Nodes with `i = nx - 1`.
    IMax,
    /// Nodes with `j = 0`.
    JMin,
    /// Nodes with `j = ny - 1`.
    JMax,
}

/// A rectangular grid of particles, flat or wrapped into a cylinder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridPanel {
    /// Particles along u and along v, `[nx, ny]` (each >= 2; nx >= 5 when wrapped).
    pub particles: [usize; 2],
    /// Extent along u and v, m. When wrapped, the first entry is the circumference.
    pub size_m: [f64; 2],
    /// Position of particle (0, 0), m; the cylinder's axis point when wrapped.
    #[serde(default)]
    pub origin_m: [f64; 3],
    /// Direction of increasing i (normalised internally). Default +x.
    #[serde(default = "default_u_axis")]
    pub u_axis: [f64; 3],
    /// Direction of increasing j (made orthogonal to u internally). Default +y.
    #[serde(default = "default_v_axis")]
    pub v_axis: [f64; 3],
    /// Wrap along u into a cylinder whose axis is v: column nx-1 links to column 0.
    #[serde(default)]
    pub wrap_u: bool,
}

fn default_u_axis() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn default_v_axis() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

/// Which of Choi & Ko's connection types a link is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LinkType {
    /// Sequential: tension-only spring.
    Sequential,
    /// Interlaced: buckling (bending) link.
    Interlaced,
    /// A seam's stitch ([`crate::SeamSpec`]).
    Seam,
}

/// The geometry and connectivity generated from one [`GridPanel`].
#[derive(Debug, Clone)]
pub struct PanelMesh {
    /// Initial (and rest) positions, index `j * nx + i`, m.
    pub positions: Vec<Vec3>,
    /// Each particle's share of the panel area, m^2 (sums to the panel area).
    pub area_share: Vec<f64>,
    /// Area of one grid cell, m^2.
    pub cell_area: f64,
    /// Type-1 links, duplicates removed.
    pub sequential: Vec<GridLink>,
    /// Type-2 links.
    pub interlaced: Vec<GridLink>,
    /// Provot's flexion links: type-2 links along the axes only (`i+2`, `j+2`).
    pub flexion: Vec<GridLink>,
    /// Two triangles per cell, counter-clockwise seen from `u x v`; the
    /// split diagonal alternates from cell to cell.
    pub triangles: Vec<[u32; 3]>,
}

/// One link of a grid panel.
///
/// `area` is the part of the panel the link stands for, m^2: in each link
/// family (along u, along v, each diagonal) the areas add up to the panel's,
/// so a family stores the continuum energy of a uniform strain or curvature
/// (see [`crate::Material`]). Interior links stand for one cell; a link
/// along a boundary line borders half a cell on one side only, so it
/// stands for half a cell. Type-2 links along a boundary take
/// a share of their own (`INTERLACED_BOUNDARY_SHARE`) instead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridLink {
    /// The two particles (local indices).
    pub ends: [u32; 2],
    /// Area the link stands for, m^2.
    pub area: f64,
    /// For links spanning two cells, the particle halfway between the ends.
    pub middle: Option<u32>,
    /// Whether the link runs along a cell diagonal (else along u or v).
    pub diagonal: bool,
}

/// Share of a cell that a type-2 link along a boundary line stands for.
///
/// Half a cell for its own area, plus a quarter for the diagonal type-2
/// links the boundary cells lack: every cell is spanned by two links of each
/// diagonal family except those along the boundary, which get one. Under a
/// curvature `kappa` along the boundary a diagonal link sees `kappa / 2`, so
/// the two missing half-links store `2 x 1/2 x 1/4 = 1/4` of what an axis
/// link of a full cell stores; the axis link on the boundary takes it over.
/// At a free edge only the curvature along the edge carries a moment
/// (Kirchhoff's free-edge conditions), so this is the stiffness that counts;
/// with a full cell a 5-row strip is 8% too stiff in bending along it.
pub(crate) const INTERLACED_BOUNDARY_SHARE: f64 = 0.75;

/// How a grid panel splits its cells into triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Diagonals {
    /// Alternating like a checkerboard: the mesh has the grid's mirror
    /// symmetries (the triangles Choi & Ko's and Provot's models collide,
    /// catch wind and draw with).
    Alternating,
    /// All from corner (i, j) to (i + 1, j + 1): every two triangles that
    /// share an edge form a parallelogram, where Volino's bending triangles
    /// read every curvature, twist included, exactly without a correction
    /// ([`crate::element_laws::curvature_stiffness`]).
    Uniform,
}

impl GridPanel {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.particles[0] * self.particles[1]
    }

    /// Whether the panel has no particles (never true for a valid panel).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Local index of node `(i, j)`.
    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.particles[0] + i
    }

    /// Checks sizes, counts and axes; names the first bad field.
    pub fn validate(&self) -> Result<(), FieldError> {
        let [nx, ny] = self.particles;
        let min_nx = if self.wrap_u { 5 } else { 2 };
        if nx < min_nx || ny < 2 {
            return Err(FieldError::new(
                "particles",
                format!("needs at least [{min_nx}, 2] particles, got [{nx}, {ny}]"),
            ));
        }
        if nx.saturating_mul(ny) > 50_000_000 {
            return Err(FieldError::new("particles", format!("{nx} x {ny} particles is too many")));
        }
        for (k, s) in self.size_m.iter().enumerate() {
            if !s.is_finite() || *s <= 0.0 {
                return Err(FieldError::new("size_m", format!("entry {k} must be finite and > 0, got {s}")));
            }
        }
        for (name, v) in [("origin_m", self.origin_m), ("u_axis", self.u_axis), ("v_axis", self.v_axis)] {
            if v.iter().any(|c| !c.is_finite()) {
                return Err(FieldError::new(name, format!("must be finite, got {v:?}")));
            }
        }
        self.frame().map(|_| ())
    }

    /// Orthonormal (u, v, n = u x v).
    pub fn frame(&self) -> Result<(Vec3, Vec3, Vec3), FieldError> {
        let u = Vec3::from(self.u_axis);
        let v = Vec3::from(self.v_axis);
        if u.norm() < 1e-12 {
            return Err(FieldError::new("u_axis", "must be non-zero"));
        }
        let u = u.normalize();
        let v_perp = v - u * u.dot(&v);
        if v_perp.norm() < 1e-9 * v.norm().max(1e-300) || v.norm() < 1e-12 {
            return Err(FieldError::new("v_axis", "must be non-zero and not parallel to u_axis"));
        }
        let v = v_perp.normalize();
        Ok((u, v, u.cross(&v)))
    }

    /// Grid spacing `(dx, dy)` in the panel's parameter plane, m.
    pub fn spacing(&self) -> (f64, f64) {
        let [nx, ny] = self.particles;
        let cols = if self.wrap_u { nx } else { nx - 1 };
        (self.size_m[0] / cols as f64, self.size_m[1] / (ny - 1) as f64)
    }

    /// Generates positions, area shares, links and triangles (diagonals
    /// alternating like a checkerboard). Call [`GridPanel::validate`] first.
    pub fn mesh(&self) -> Result<PanelMesh, FieldError> {
        self.mesh_with(Diagonals::Alternating)
    }

    /// [`GridPanel::mesh`] with the cells split along `diagonals`.
    pub fn mesh_with(&self, diagonals: Diagonals) -> Result<PanelMesh, FieldError> {
        self.validate()?;
        let (u, v, n) = self.frame()?;
        let [nx, ny] = self.particles;
        let (dx, dy) = self.spacing();
        let origin = Vec3::from(self.origin_m);
        let radius = self.size_m[0] / (2.0 * std::f64::consts::PI);
        let mut positions = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let along_u = if self.wrap_u {
                    let theta = 2.0 * std::f64::consts::PI * i as f64 / nx as f64;
                    (u * theta.cos() + n * theta.sin()) * radius
                } else {
                    u * (i as f64 * dx)
                };
                positions.push(origin + along_u + v * (j as f64 * dy));
            }
        }
        // Neighbour (i + di, j + dj), wrapping in i when the panel is a cylinder.
        let neighbour = |i: usize, j: usize, di: isize, dj: usize| -> Option<u32> {
            let jj = j + dj;
            if jj >= ny {
                return None;
            }
            let ii = i as isize + di;
            let ii = if self.wrap_u {
                ii.rem_euclid(nx as isize) as usize
            } else if ii < 0 || ii >= nx as isize {
                return None;
            } else {
                ii as usize
            };
            Some(self.index(ii, jj) as u32)
        };
        let cell_area = dx * dy;
        // Grid lines on the boundary: rows 0 and ny-1, and columns 0 and
        // nx-1 unless the panel is wrapped.
        let on_boundary = |i: usize, j: usize, along_u: bool| {
            if along_u { j == 0 || j == ny - 1 } else { !self.wrap_u && (i == 0 || i == nx - 1) }
        };
        let links = |step: usize, diagonals: bool, boundary_share: f64| -> Vec<GridLink> {
            let s = step as isize;
            let offsets = [(s, 0), (0, step), (s, step), (-s, step)];
            let offsets = if diagonals { &offsets[..] } else { &offsets[..2] };
            let mut out = Vec::with_capacity(4 * nx * ny);
            let mut seen = std::collections::HashSet::new();
            for j in 0..ny {
                for i in 0..nx {
                    let a = self.index(i, j) as u32;
                    for &(di, dj) in offsets {
                        if let Some(b) = neighbour(i, j, di, dj)
                            && a != b
                            && seen.insert((a.min(b), a.max(b)))
                        {
                            let axis = di == 0 || dj == 0;
                            let share = if axis && on_boundary(i, j, dj == 0) { boundary_share } else { 1.0 };
                            let middle = if step == 2 { neighbour(i, j, di / 2, dj / 2) } else { None };
                            out.push(GridLink { ends: [a, b], area: share * cell_area, middle, diagonal: !axis });
                        }
                    }
                }
            }
            out
        };
        let mut area_share = vec![0.0; nx * ny];
        let mut triangles = Vec::new();
        let cells_u = if self.wrap_u { nx } else { nx - 1 };
        for j in 0..ny - 1 {
            for i in 0..cells_u {
                let a = self.index(i, j) as u32;
                let b = neighbour(i, j, 1, 0).expect("cell corner exists");
                let c = neighbour(i, j, 1, 1).expect("cell corner exists");
                let d = neighbour(i, j, 0, 1).expect("cell corner exists");
                for p in [a, b, c, d] {
                    area_share[p as usize] += 0.25 * cell_area;
                }
                if diagonals == Diagonals::Uniform || (i + j) % 2 == 0 {
                    triangles.push([a, b, c]);
                    triangles.push([a, c, d]);
                } else {
                    triangles.push([a, b, d]);
                    triangles.push([b, c, d]);
                }
            }
        }
        Ok(PanelMesh {
            positions,
            area_share,
            cell_area,
            sequential: links(1, true, 0.5),
            interlaced: links(2, true, INTERLACED_BOUNDARY_SHARE),
            flexion: links(2, false, 0.5),
            triangles,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An `nx x ny` panel 1 m x 0.5 m in the xy plane at the origin.
    pub(crate) fn panel(nx: usize, ny: usize, wrap_u: bool) -> GridPanel {
        GridPanel {
            particles: [nx, ny],
            size_m: [1.0, 0.5],
            origin_m: [0.0; 3],
            u_axis: [1.0, 0.0, 0.0],
            v_axis: [0.0, 1.0, 0.0],
            wrap_u,
        }
    }

    #[test]
    fn flat_grid_has_the_choi_ko_link_counts() {
        let (nx, ny) = (6, 4);
        let m = panel(nx, ny, false).mesh().unwrap();
        // Structure (nx-1)ny + nx(ny-1), shear 2(nx-1)(ny-1).
        assert_eq!(m.sequential.len(), (nx - 1) * ny + nx * (ny - 1) + 2 * (nx - 1) * (ny - 1));
        assert_eq!(m.interlaced.len(), (nx - 2) * ny + nx * (ny - 2) + 2 * (nx - 2) * (ny - 2));
        assert_eq!(m.triangles.len(), 2 * (nx - 1) * (ny - 1));
        assert_eq!(m.flexion.len(), (nx - 2) * ny + nx * (ny - 2));
        let area: f64 = m.area_share.iter().sum();
        assert!((area - 0.5).abs() < 1e-15);
        assert!((m.positions[m.positions.len() - 1] - Vec3::new(1.0, 0.5, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn wrapped_grid_closes_into_a_cylinder() {
        let (nx, ny) = (8, 3);
        let m = panel(nx, ny, true).mesh().unwrap();
        assert_eq!(m.sequential.len(), nx * ny + nx * (ny - 1) + 2 * nx * (ny - 1));
        assert_eq!(m.interlaced.len(), nx * ny + nx * (ny - 2) + 2 * nx * (ny - 2));
        let area: f64 = m.area_share.iter().sum();
        assert!((area - 0.5).abs() < 1e-15);
        let r = 1.0 / (2.0 * std::f64::consts::PI);
        for p in &m.positions {
            assert!(((p.x * p.x + p.z * p.z).sqrt() - r).abs() < 1e-15);
        }
    }

    #[test]
    fn invalid_panels_name_the_field() {
        let mut p = panel(1, 4, false);
        assert_eq!(p.validate().unwrap_err().path, "particles");
        p = panel(4, 4, true);
        assert_eq!(p.validate().unwrap_err().path, "particles");
        p = panel(4, 4, false);
        p.size_m[1] = f64::NAN;
        assert_eq!(p.validate().unwrap_err().path, "size_m");
        p = panel(4, 4, false);
        p.v_axis = [2.0, 0.0, 0.0];
        assert_eq!(p.validate().unwrap_err().path, "v_axis");
    }
}
