//! Garments made finer (`cloth bench garments`): those that hold at the
//! paper's counts and at twice their Table-1 count keep holding. The 4x
//! runs are the bench's (`docs/results/garments-primitives.md`).

mod common;

use common::cloth;
use std::path::Path;

/// Runs `cloth bench garments` on the primitives mannequin, once each,
/// for `garments` at `scale`, and checks that each holds with the given
/// particle count: peak stretch under 1.15, no particle deeper inside a
/// solid than the contact thickness, no lasting crossing, seams closed.
fn garments_hold(garments: &str, scale: &str, particles: &[u64]) {
    let out = std::env::temp_dir().join(format!("cloth-garments-{scale}x-{}", std::process::id()));
    let o = cloth()
        .current_dir(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")))
        .args(["bench", "garments", "--garment", garments])
        .args(["--scale", scale, "--repeat", "1"])
        .args(["--mannequin", "primitives", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("garments.json")).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), particles.len());
    for (r, &count) in rows.iter().zip(particles) {
        assert_eq!(r["particles"], count, "{r}");
        assert!((r["sim_time_s"].as_f64().unwrap() - 3.0).abs() < 1e-6, "{r}");
        assert_eq!(r["fails"].as_array().unwrap().len(), 0, "{r}");
        assert!(r["peak_stretch"].as_f64().unwrap() < 1.15, "{r}");
        assert_eq!(r["deep_in_solids_max"], 0, "{r}");
        assert!(r["lasting_crossing"].is_null(), "{r}");
    }
    std::fs::remove_dir_all(&out).ok();
}

/// Every Table-1 garment walks the 3 s on the primitives mannequin at
/// twice its Table-1 count and holds: the one-piece (12,056 particles),
/// the top (6,296), the skirt (7,776), the dress (10,692), the pattern
/// skirt (7,056), the T-shirt (6,741), the flared skirt (6,840) and the
/// OBJ skirt (7,776). Peak stretch measured: 1.112, 1.100, 1.100, 1.109,
/// 1.100, 1.100, 1.100 and 1.100. They hold with the
/// deformation constraints' fast projections, which keep the particles
/// out of the solids near them in the same solve (without them the dress
/// peaked at 1.15 where its waist seam sits on the pelvis box, and the
/// OBJ skirt at 1.49 at 4x where a shin struck its hem), with stitches
/// that close within half the contact thickness (a strap's corner stitch
/// of the one-piece stayed 2.2 mm open), with seams in the self-collision
/// exclusions on both sides of a link, and with the self-collision
/// contacts' couplings in the solve (the T-shirt and the top peaked at
/// 1.28 and 1.27 without them). The 4x runs are the bench's.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn garments_hold_at_twice_their_table1_count() {
    garments_hold(
        "one-piece,top,skirt,pattern-dress,pattern-skirt,pattern-tshirt,flared-skirt,obj-skirt",
        "2",
        &[12056, 6296, 7776, 10692, 7056, 6741, 6840, 7776],
    );
}

/// The one-piece (5,458 particles), the T-shirt (3,411) and the flared
/// skirt (3,482) at Table 1's counts, the paper's or finer, hold (peak
/// stretch 1.101, 1.100 and 1.100; the one-piece under Provot's
/// constraints, 1.472 without: the shins striking its hem). The
/// flared skirt there kept a crossing between the knees while the impact
/// zones did not see what the deformation constraints moved, missed edges
/// of triangles round one vertex, and left meetings where a leg pushed
/// both layers.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn garments_hold_at_the_papers_counts() {
    garments_hold("one-piece,pattern-tshirt,flared-skirt", "1", &[5458, 3411, 3482]);
}
