//! The pattern mesher against random outlines. (The readers of user
//! files and the FMU's C API are fuzzed by `cloth-fuzz`.)

use cloth_fuzz::mutate::Rng;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

/// Random pattern outlines (3 to 12 corners anywhere in a square, so
/// often self-crossing; repeated, collinear and nearly coincident corners;
/// lines inside and out; edge lengths from far too fine to coarser than
/// the piece) are meshed or refused, never a panic, and what is meshed is
/// a mesh the model takes: consistently wound, manifold, every vertex used.
#[test]
fn random_pattern_outlines_are_meshed_or_refused() {
    use cloth_core::{MeshPanel, PatternPiece};
    let mut rng = Rng(0x5eed_0f9a_77e2);
    let unit = |rng: &mut Rng| (rng.bits() >> 11) as f64 / (1u64 << 53) as f64;
    let (mut meshed, mut refused, mut triangulator) = (0, 0, 0);
    cloth_fuzz::quiet_panics();
    {
        for round in 0..400 {
            let n = 3 + rng.below(10);
            let mut outline: Vec<[f64; 2]> = (0..n).map(|_| [unit(&mut rng) - 0.5, unit(&mut rng) - 0.5]).collect();
            // Sorted by angle about the middle: star-shaped, never self-crossing.
            if rng.below(2) == 0 {
                outline.sort_by(|a, b| a[1].atan2(a[0]).total_cmp(&b[1].atan2(b[0])));
            }
            match rng.below(5) {
                0 => outline[n - 1] = outline[0],                         // repeated
                1 => outline[1] = [outline[0][0] + 1e-13, outline[0][1]], // nearly coincident
                2 => outline[1] = [(outline[0][0] + outline[2][0]) / 2.0, (outline[0][1] + outline[2][1]) / 2.0],
                _ => {}
            }
            // Lines from a corner towards the middle (inside a star-shaped
            // outline, often outside another).
            let lines = (0..rng.below(4).saturating_sub(2))
                .map(|_| [outline[rng.below(n)], [0.1 * unit(&mut rng), 0.0]])
                .collect();
            let edge_length_m = [1e-4, 0.01, 0.05, 0.2, 2.0][rng.below(5)];
            let piece = PatternPiece {
                outline_m: outline,
                edge_length_m,
                lines_m: lines,
                u_axis: [1.0, 0.0, 0.0],
                v_axis: [0.0, 1.0, 0.0],
                cylinder_radius_m: None,
                cone: None,
            };
            let result =
                catch_unwind(AssertUnwindSafe(|| MeshPanel::from_pattern(piece.clone()).resolve(Path::new("."))));
            match result {
                Err(_) => panic!("round {round}: meshing panicked on {piece:?}"),
                Ok(Ok(mesh)) => {
                    assert!(mesh.check().is_ok(), "round {round}");
                    meshed += 1;
                }
                Ok(Err(e)) => {
                    refused += 1;
                    triangulator += usize::from(e.message.contains("triangulator"));
                }
            }
        }
    }
    println!("{meshed} meshed, {refused} refused ({triangulator} by the triangulator's own panic, caught)");
    assert!(meshed > 100 && refused > 100, "{meshed} meshed, {refused} refused: the cases miss one side");
}
