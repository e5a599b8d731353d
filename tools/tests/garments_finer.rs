//! Garments made finer (`cloth bench garments`): those that hold at the
//! paper's counts and at twice their Table-1 count keep holding. The 4x runs are the bench's
//! (`docs/results/garments-primitives.md`, which also lists the garments
//! that do not hold yet).

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

/// Six garments walk the 3 s on the primitives mannequin at twice their
/// Table-1 counts and hold: the top (6,296 particles), the skirt (7,776),
/// the pattern skirt (7,056), the T-shirt (6,741), the flared skirt
/// (6,840) and the OBJ skirt (7,776); peak stretch measured 1.100, 1.100,
/// 1.100, 1.1005, 1.100 and 1.1465. The T-shirt and the top hold since
/// the self-collision contacts' couplings are in the solve (1.282 and
/// 1.265 before, layers ringing where they touch). The pattern skirt holds by the
/// automatic Newton step on the steps a leg strikes it
/// (`solver.newton.auto_trigger`); with the single linearised step it
/// tangles (peak stretch 4.1). The dress (1.1496, 1.1518 at h = 1/89 s)
/// and the one-piece (1.1486 with a stitch 2.3 mm open) are the bench's.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn garments_hold_at_twice_their_table1_count() {
    garments_hold(
        "top,skirt,pattern-skirt,pattern-tshirt,flared-skirt,obj-skirt",
        "2",
        &[6296, 7776, 7056, 6741, 6840, 7776],
    );
}

/// The one-piece (5,458 particles), the T-shirt (3,411) and the flared
/// skirt (3,482) at Table 1's counts, the paper's or finer, hold (peak
/// stretch 1.139, 1.100 and 1.100; the one-piece under Provot's
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
