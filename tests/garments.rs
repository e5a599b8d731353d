//! Garments on a URDF character: the skirt of `fixtures/scenes/skirt-walk.toml`
//! on the mannequin, which stands while the skirt settles, then walks
//! (BVH) two and a half cycles, and of `skirt-turn.toml`, where it turns
//! and raises its arms; the top (`top-walk.toml`) and the one-piece
//! (`one-piece-walk.toml`), sewn from panels while the mannequin stands,
//! held up by their straps alone. Contacts with every link, friction and
//! self-collision at h = 1/90 s.

use cloth_core::Vec3;
use cloth_rapier::convert::{pose_from_rapier, vec_from_rapier};
use cloth_rapier::rapier3d_f64::prelude::RigidBodyHandle;
use cloth_rapier::{CoupledRun, CoupledScene};
use cloth_tests::{fixture, min_unlinked_point_triangle, same_bits};

fn build(scene: &str, overrides: &[&str]) -> CoupledRun {
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    CoupledScene::load(&fixture(scene), &overrides).unwrap().build().unwrap()
}

fn skirt(overrides: &[&str]) -> CoupledRun {
    build("skirt-walk.toml", overrides)
}

/// Every link body is where forward kinematics of the motion puts it at
/// the end of each step (rapier moved it there, nothing else did).
#[test]
fn the_rig_links_follow_forward_kinematics() {
    let mut run = skirt(&["simulation.duration_s=1.0"]);
    let mut poses = Vec::new();
    let mut worst: f64 = 0.0;
    for _ in 0..run.config.steps {
        run.step().unwrap();
        let t = run.cloths[run.cloth].simulation().time();
        let rig = run.rig.as_ref().unwrap();
        rig.rig.link_poses(&rig.pose_at(t), &mut poses).unwrap();
        for (handle, expected) in rig.bodies.handles.iter().zip(&poses) {
            let at = pose_from_rapier(run.world.bodies[*handle].position());
            worst = worst.max((at.position - expected.translation.vector).norm());
            worst = worst.max(at.rotation.angle_to(&expected.rotation));
        }
    }
    assert!(worst < 1e-12, "a link is {worst} (m or rad) from its forward-kinematics pose");
}

/// What a garment did over a run, measured at every step.
struct Worn {
    /// Deepest particle inside any link, m.
    deepest: f64,
    /// Largest link stretch from the end of the stand (0.6 s) on.
    stretch: f64,
    /// Mean over the steps from the end of the stand on of each step's
    /// largest link stretch: how stretched the worn garment typically is.
    typical: f64,
    /// Largest link stretch before the end of the stand, when garments are sewn.
    sewing: f64,
    /// Closest particle to a triangle not linked to it (every third step), m.
    closest: f64,
    /// The self-collision thickness, m.
    thickness: f64,
    /// Farthest particle from the axis of the link the garment is worn on, m.
    radial: f64,
    /// Lowest and highest particle in that link's frame, m.
    low: f64,
    high: f64,
    /// Widest seam gap once the garment is sewn (after the stand), m.
    seam_gap: f64,
    /// The run at its end.
    run: CoupledRun,
}

/// Maps a point to the frame of rig body `link` as it is now, with the
/// rig file's up axis along z.
fn in_link_frame(run: &CoupledRun, link: RigidBodyHandle) -> impl Fn(&Vec3) -> Vec3 {
    let frame = pose_from_rapier(run.world.bodies[link].position());
    let up = run.rig.as_ref().unwrap().rig.up;
    move |p| up * (frame.rotation.inverse() * (p - frame.position))
}

/// Runs `scene`, measuring in the frame of link `on`.
fn wear(scene: &str, on: &str, overrides: &[&str]) -> Worn {
    let mut run = build(scene, overrides);
    let link = run.rig.as_ref().unwrap().body(on).unwrap();
    let sewn_at = (0.6 / run.config.dt_s).round() as u64;
    let mut seam_gap: f64 = 0.0;
    let mut stretch_sum = 0.0;
    let mut sewing: f64 = 0.0;
    let thickness = run.cloths[run.cloth].simulation().model().self_collision().unwrap().thickness_m;
    let (mut deepest, mut stretch, mut closest): (f64, f64, f64) = (0.0, 0.0, f64::INFINITY);
    let (mut radial, mut low, mut high): (f64, f64, f64) = (0.0, 0.0, f64::NEG_INFINITY);
    for step in 0..run.config.steps {
        run.step().unwrap();
        let sim = run.cloths[run.cloth].simulation();
        let x = &sim.state().x;
        deepest = deepest.max(sim.max_penetration());
        // The garment as worn: a sewn one from the end of the stand.
        let now = sim.model().max_stretch_ratio(x);
        if step >= sewn_at {
            stretch = stretch.max(now);
            stretch_sum += now;
        } else {
            sewing = sewing.max(now);
        }
        if step % 3 == 2 {
            closest = closest.min(min_unlinked_point_triangle(sim.model(), x));
        }
        if step >= sewn_at {
            seam_gap = seam_gap.max(sim.model().max_seam_gap(x));
        }
        let to_link = in_link_frame(&run, link);
        for p in x {
            let local = to_link(p);
            radial = radial.max(local.xy().norm());
            low = low.min(local.z);
            high = high.max(local.z);
        }
    }
    let typical = stretch_sum / run.config.steps.saturating_sub(sewn_at).max(1) as f64;
    println!(
        "{scene}: deepest {deepest:.2e} m, stretch {stretch:.4} (typically {typical:.4}; {sewing:.4} while \
         sewn), closest particle-triangle {closest:.4} m \
         (thickness {thickness}), radial {radial:.3} m, z {low:.3}..{high:.3} m about the {on}, \
         seams within {seam_gap:.2e} m"
    );
    Worn { deepest, stretch, typical, sewing, closest, thickness, radial, low, high, seam_gap, run }
}

impl Worn {
    /// No particle inside a link, no link stretched to `stretch`, no
    /// particle closer than 0.68 of the self-collision thickness to a
    /// triangle not linked to it (the separation keeps 0.75; the
    /// one-piece's closest, 4.13 mm at 6 mm, is where a shin strikes the
    /// hem: 4.13-9.3 mm at h = 1/89, 1/90, 1/91 s, 4.35-9.3 mm before
    /// the self-collision couplings were in the solve; the fold test
    /// allows 0.65), and every
    /// particle where the garment is worn: within `radial` m of the link's
    /// axis and between `z` m along it.
    fn assert_stays_on(&self, stretch: f64, radial: f64, z: [f64; 2]) {
        let Worn { deepest, closest, thickness, low, high, .. } = *self;
        assert!(deepest <= 0.0, "a particle {deepest} m inside a link");
        assert!(self.stretch < stretch, "stretch {}", self.stretch);
        assert!(closest >= 0.68 * thickness, "a particle {closest} m from a triangle, thickness {thickness} m");
        assert!(
            self.radial < radial && low > z[0] && high < z[1],
            "the garment left its place: {} m out, {low}..{high} m",
            self.radial
        );
    }
}

/// Over the stand and two and a half walk cycles the skirt stays on
/// ([`Worn::assert_stays_on`]: within 0.35 m of the pelvis's axis, from
/// 0.40 m below the hip joints (the hem hangs 0.37 m below them) to 0.15 m
/// above; measured: nothing inside a link, stretch 1.0562, closest 36 mm:
/// this skirt's folds do not close, radial 0.325 m, down to 0.372 m) and
/// walks the 2.5 m with the mannequin (centroid within 2 cm of the hips'
/// x; measured 0.2 mm).
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_skirt_stays_on_the_walking_mannequin() {
    let worn = wear("skirt-walk.toml", "pelvis", &[]);
    worn.assert_stays_on(1.1, 0.35, [-0.40, 0.15]);
    let run = &worn.run;
    let sim = run.cloths[run.cloth].simulation();
    let centroid = sim.state().x.iter().sum::<Vec3>() / sim.state().x.len() as f64;
    let pelvis = run.rig.as_ref().unwrap().body("pelvis").unwrap();
    let hips = vec_from_rapier(run.world.bodies[pelvis].translation());
    println!("hips at x {:.3} m, skirt centroid {:.3} m", hips.x, centroid.x);
    assert!(hips.x > 2.49, "the mannequin walked {} m", hips.x);
    assert!((centroid.x - hips.x).abs() < 0.02, "the skirt is at x {} m, the hips at {} m", centroid.x, hips.x);
}

/// Two characters more, each with a garment and a keyframed walk: a
/// humanoid built unlike the mannequin (`humanoid-skirt.toml`: Y up,
/// centimetres, its own names) and the mannequin's triangle-mesh twin
/// (`skirt-mesh-keys.toml`). The skirts stay on (measured: nothing inside a
/// link; peak stretch 1.1139, where the knee swings into the hem, and
/// 1.0473) and walk with the hips.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn skirts_stay_on_other_characters_walking_keyframes() {
    for (scene, hips, forward, stretch) in
        [("humanoid-skirt.toml", "Hips", -Vec3::y(), 1.12), ("skirt-mesh-keys.toml", "pelvis", Vec3::x(), 1.05)]
    {
        let worn = wear(scene, hips, &[]);
        worn.assert_stays_on(stretch, 0.35, [-0.40, 0.15]);
        let run = &worn.run;
        let sim = run.cloths[run.cloth].simulation();
        let centroid = sim.state().x.iter().sum::<Vec3>() / sim.state().x.len() as f64;
        let body = run.rig.as_ref().unwrap().body(hips).unwrap();
        let at = vec_from_rapier(run.world.bodies[body].translation());
        println!(
            "{scene}: hips {:.3} m along the walk, skirt centroid {:.3} m",
            at.dot(&forward),
            centroid.dot(&forward)
        );
        assert!(at.dot(&forward) > 2.49, "{scene}: walked {} m", at.dot(&forward));
        assert!((centroid - at).dot(&forward).abs() < 0.03, "{scene}: the skirt is behind the hips");
    }
}

/// Skirts that are not grids stay on as the grid's tube does and walk
/// with the hips: cut from pattern pieces (`pattern-skirt-walk.toml`:
/// front and back meshed irregularly, two side seams; measured: nothing
/// inside a link, stretch 1.1219 at its worst step (where the knee
/// strikes the hem by the front seam; 1.0836, 1.1219, 1.1384 at
/// h = 1/89, 1/90, 1/91 s, 1.066-1.138 over these, 1/88 and 1/92 s and
/// `rel_tol` 5e-4; 1.072-1.114 over the same eight before the multigrid
/// took the self-collision couplings, and 1.140, 1.0993, 1.1918 at the
/// first three before the couplings were in the solve), typically 1.0115,
/// closest 5.3 mm at a 6 mm thickness, radial 0.309 m, down to 0.372 m,
/// seams within 2.4 um with its stitches at 100 x E, 2.2 mm at the default 10 x E) and
/// read from an OBJ (`obj-skirt-walk.toml`, a closed irregular tube;
/// measured: stretch 1.0805, typically 1.0096, closest 11.5 mm). The
/// grid's tube: 1.0562.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn skirts_from_patterns_and_obj_files_stay_on_the_walking_mannequin() {
    for (scene, stretch) in [("pattern-skirt-walk.toml", 1.13), ("obj-skirt-walk.toml", 1.09)] {
        let worn = wear(scene, "pelvis", &[]);
        worn.assert_stays_on(stretch, 0.35, [-0.40, 0.15]);
        assert!(worn.seam_gap < 1e-5, "{scene}: a seam opened by {} m", worn.seam_gap);
        let run = &worn.run;
        let sim = run.cloths[run.cloth].simulation();
        let centroid = sim.state().x.iter().sum::<Vec3>() / sim.state().x.len() as f64;
        let pelvis = run.rig.as_ref().unwrap().body("pelvis").unwrap();
        let hips = vec_from_rapier(run.world.bodies[pelvis].translation());
        assert!(
            (centroid.x - hips.x).abs() < 0.02,
            "{scene}: the skirt is at x {} m, the hips at {} m",
            centroid.x,
            hips.x
        );
    }
}

/// How far out (m) from link `on`'s axis the hem reaches at the end of
/// the run: the farthest of the particles within 3 cm of the lowest.
fn hem_reach(worn: &Worn, on: &str) -> f64 {
    let run = &worn.run;
    let to_link = in_link_frame(run, run.rig.as_ref().unwrap().body(on).unwrap());
    let local: Vec<Vec3> = run.cloths[run.cloth].simulation().state().x.iter().map(to_link).collect();
    let lowest = local.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    local.iter().filter(|p| p.z < lowest + 0.03).map(|p| p.xy().norm()).fold(0.0, f64::max)
}

/// The flared skirt (`pattern-flared-skirt-walk.toml`: two gores cut as
/// half annuli, started on their cone, held at the waist arc, sewn at the
/// sides) stays on through the walk, sewn, and its hem hangs out as cut
/// (measured: nothing inside a link, stretch 1.0625, typically 1.0111,
/// closest 5.2 mm, 0.429 m out at most, from 0.321 m below the hip joints,
/// seams within 2.1 um; stretch 1.0288, 1.0625, 1.0586 at h = 1/89, 1/90,
/// 1/91 s, and 1.0630, 1.0518, 1.0426 before the multigrid took the
/// self-collision couplings). Its hem, in folds, reaches 0.352 m from the
/// pelvis's axis at the end; the straight pattern skirt's 0.278 m.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_flared_pattern_skirt_stays_on_the_walking_mannequin() {
    let worn = wear("pattern-flared-skirt-walk.toml", "pelvis", &[]);
    worn.assert_stays_on(1.065, 0.45, [-0.35, 0.12]);
    assert!(worn.seam_gap < 1e-5, "a seam opened by {} m", worn.seam_gap);
    let straight = wear("pattern-skirt-walk.toml", "pelvis", &[]);
    let (flared, straight) = (hem_reach(&worn, "pelvis"), hem_reach(&straight, "pelvis"));
    println!("hem from the pelvis's axis: flared {flared:.3} m, straight {straight:.3} m");
    assert!(flared > straight + 0.05, "the hem reaches {flared} m, the straight skirt's {straight} m");
}

/// Through two looped quarter turns with the arms raised and lowered the
/// skirt stays on (measured: stretch 1.0595) and turns with the hips: the
/// mannequin ends half a turn round, and so does the skirt's seam.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_skirt_turns_with_the_mannequin() {
    let worn = wear("skirt-turn.toml", "pelvis", &[]);
    worn.assert_stays_on(1.1, 0.35, [-0.40, 0.15]);
    let run = &worn.run;
    let pelvis = run.rig.as_ref().unwrap().body("pelvis").unwrap();
    let frame = pose_from_rapier(run.world.bodies[pelvis].position());
    let (_, _, yaw) = frame.rotation.euler_angles();
    // The seam's hem particle (column 0, last row) started in front (+x)
    // of the hips; after half a turn it is behind them.
    let sim = run.cloths[run.cloth].simulation();
    let hem = sim.state().x[15 * 48] - frame.position;
    println!("yaw {:.2} deg, seam's hem at {:.3} {:.3} from the hips", yaw.to_degrees(), hem.x, hem.y);
    // (The file's frame time, 0.03333333 s, makes two cycles 0.4 us short
    // of the run's 4 s: 1.3e-8 rad further round.)
    assert!((yaw.abs() - std::f64::consts::PI).abs() < 1e-7, "the mannequin turned {} deg", yaw.to_degrees());
    assert!(hem.x < -0.2 && hem.y.abs() < 0.1, "the seam's hem is at {hem} from the hips");
}

/// The same scene twice, on one thread and on two: the same bits (the
/// skirt, and the top through its sewing and into the walk).
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn garment_reruns_are_bit_identical_on_one_and_two_threads() {
    for scene in ["skirt-walk.toml", "top-walk.toml"] {
        let run_on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut run = build(scene, &["simulation.duration_s=1.2"]);
                for _ in 0..run.config.steps {
                    run.step().unwrap();
                }
                run.cloths[run.cloth].simulation().state().x.clone()
            })
        };
        let (one, two) = (run_on(1), run_on(2));
        assert!(same_bits(&one, &two), "{scene}: one and two threads differ");
        assert!(same_bits(&two, &run_on(2)), "{scene}: two runs on two threads differ");
    }
}

impl Worn {
    /// Sewn garments: the seams closed while the mannequin stood and stay
    /// closed within `gap` m (the contact thickness is 5 mm), the panels
    /// stretched less than `sewing` while they were drawn together, and
    /// the worn garment's largest link stretch below `typical` on average
    /// over the steps (a garment's edge may stay stretched where it is
    /// caught on a link: its peak is [`Worn::assert_stays_on`]'s).
    fn assert_sewn(&self, gap: f64, sewing: f64, typical: f64) {
        assert!(self.seam_gap < gap, "a seam opened to {} m", self.seam_gap);
        assert!(self.sewing < sewing, "stretched to {} while sewn", self.sewing);
        assert!(self.typical < typical, "typically stretched to {}", self.typical);
    }
}

/// The top, sewn from a tube and two straps while the mannequin stands,
/// stays on through two and a half walk cycles held by its straps alone
/// (in the torso's frame, whose origin is the waist joint: measured
/// nothing inside a link, stretch 1.273 (the straps' inner edges where
/// they cross the ridge of the shoulder line, under the single linearised
/// step), typically 1.109, 1.150 while sewn, closest
/// particle-triangle 7.3 mm, 0.283 m from the torso's axis, 0.003 m below
/// the waist joint to 0.504 m above it, seams within 0.1 mm). The limits
/// cover what the walk does within the solve's tolerance, not one
/// trajectory: at `rel_tol` 1e-3, 3e-4, 1e-4 and 1e-5 over three versions
/// of the multigrid and three of the contact response (`cloth run ... --set
/// solver.rel_tol=`), the worn top reached 1.244-1.362, 1.153-1.289 while
/// sewn; with held contacts kept from bouncing (the fourth response) 1.268-1.293,
/// typically 1.109-1.118, 1.150-1.191 while sewn.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_sewn_top_stays_on_the_walking_mannequin() {
    let worn = wear("top-walk.toml", "torso", &[]);
    worn.assert_stays_on(1.37, 0.30, [-0.05, 0.55]);
    worn.assert_sewn(1e-3, 1.32, 1.13);
}

/// The one-piece: the top with a skirt gathered onto its lower edge
/// (measured: stretch 1.442, typically 1.263, 1.414 while sewn, closest
/// 4.1 mm, 0.398 m out, from 0.627 m below the waist joint, seams within
/// 0.7 mm). While it is sewn the stitches draw the tube's lower edge down
/// over the pelvis box, which is wider than the tube, and the edge's
/// links stretch: 2.45 when open stitches pulled with the seam's full
/// strength, 1.35 with the sewing pull (a quarter of it) until each
/// stitch has closed. Worn, the tube's edge may stay caught over the hip,
/// sliding against friction (mu 0.3) with the body, one link at about
/// 1.25 for the whole walk, and the skirt catches on the swinging thighs
/// now and then; whether and how long it is caught is chaotic in the
/// solve's error. At `rel_tol` 2e-3, 1e-3, 7e-4, 5e-4, 3e-4, 2e-4, 1e-4
/// and 1e-5, and at 1e-3 with `solver.contacts.settling_iterations` 0 and 6 (the
/// scene's 4), the worn one-piece reached 1.259-1.464, typically
/// 1.132-1.262 (the scene's own run is the one caught all walk: 216 of
/// 216 steps beyond 1.2, against 5-155 in the others), 1.356-1.414 while
/// sewn (at the four tolerances 1e-3 to 1e-5). Before held contacts were
/// kept from bouncing the contact held every other step and its friction
/// with it: then the same walk typically stretched to 1.13-1.16, and as
/// much as 1.15 with half the friction on the new response (mu 0.15: 30
/// steps beyond 1.2; mu 0: 1 step). The 1.455 while sewn the sewing
/// limit allows was one step of a strap's link on the shoulder, which
/// jumps between 0.89 and 1.46 from step to step while the skirt's
/// stitches close. Since stitches close within half the contact
/// thickness and triangles never repel the particles sewn to their
/// corners' neighbours, the scene's own run typically stretches to 1.279
/// (1.442 worn, 1.372 while sewn, seams within 0.71 mm); at h = 1/89,
/// 1/90 and 1/91 s and `rel_tol` 1e-3 and 5e-4, typically 1.128-1.279,
/// worn 1.200-1.442, sewn 1.349-1.407. This fixture runs without the
/// deformation constraints that Table 1's one-piece has.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_sewn_one_piece_stays_on_the_walking_mannequin() {
    let worn = wear("one-piece-walk.toml", "torso", &[]);
    worn.assert_stays_on(1.5, 0.45, [-0.65, 0.55]);
    worn.assert_sewn(1e-3, 1.46, 1.28);
}

/// Volino's and Provot's models wear the sewn top too (their membranes,
/// hinges and flexion springs stop at the seams as Choi & Ko's links do):
/// measured, nothing inside a link, seams within 0.2 mm, every particle
/// where the top is worn; stretch while sewn and worn 1.071 and 1.089,
/// typically 1.058 (volino), 1.108 and 1.113, typically 1.097 (provot).
/// Limits from the spread at `rel_tol` 1e-3, 3e-4, 1e-4 and 1e-5 over
/// three versions of the multigrid and three of the contact response:
/// volino 1.072-1.103 sewn, 1.067-1.314 worn; provot 1.105-1.127 and
/// 1.107-1.240: one trajectory in four reaches each worn peak; with held
/// contacts kept from bouncing volino 1.071-1.082 and 1.089-1.127,
/// typically 1.058-1.061, provot 1.108-1.127 and 1.105-1.113, typically
/// 1.094-1.097.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_sewn_top_stays_on_in_every_model() {
    for (model, sewing, worn_stretch, typical) in [("volino", 1.11, 1.32, 1.07), ("provot", 1.13, 1.25, 1.10)] {
        let worn = wear("top-walk.toml", "torso", &[&format!("simulation.model=\"{model}\"")]);
        worn.assert_stays_on(worn_stretch, 0.30, [-0.05, 0.55]);
        worn.assert_sewn(1e-3, sewing, typical);
    }
}

/// The T-shirt cut from a sewing pattern (`pattern-tshirt-walk.toml`: body
/// front and back, two shoulder pieces, two set-in sleeves with caps,
/// sixteen seams) is sewn with the arms raised and stays on through the
/// walk under Provot's deformation constraints (measured: nothing inside
/// a link, stretch 1.1000, typically 1.0803 (1.0797-1.0803 at h = 1/89,
/// 1/90, 1/91 s; 1.0789-1.0800 before the multigrid took the
/// self-collision couplings), 1.1000 while sewn, closest
/// 4.5 mm, 0.416 m out, from the waist joint to 0.507 m above it, seams
/// shut to 1e-12 m). Without the constraints: stretch 1.2244 for one step
/// (a hem particle on the pelvis's rear edge slides 12 mm back while its
/// neighbour moves on with the body), seams open 2.5 mm for one step
/// where a sleeve's cap meets the shoulder piece as the arm swings.
/// Stiffer stitches (20 and 30 x E) left gathered cap stitches open by
/// 1-5 mm. With long sleeves (0.16 m under the arm) or no cap the sleeve
/// caught between arm and torso once it walked (stretch 4.6 to 6.5).
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_pattern_tshirt_stays_on_the_walking_mannequin() {
    let worn = wear("pattern-tshirt-walk.toml", "torso", &[]);
    worn.assert_stays_on(1.101, 0.43, [-0.02, 0.52]);
    worn.assert_sewn(1e-9, 1.101, 1.081);
}

/// The dress cut from a sewing pattern (`pattern-dress-walk.toml`: bodice
/// front and back, two straps, skirt front and back, ten seams, the skirt
/// gathered 1.64 times onto the bodice) is sewn while the mannequin stands
/// and stays on its straps through the walk under Provot's deformation
/// constraints (measured: nothing inside a link, stretch 1.1000,
/// typically 1.0778, 1.1081 while sewn (the bodice's lower corners, where
/// the gathered skirt is drawn up), closest 5.4 mm, 0.412 m out, from
/// 0.626 m below the waist joint, seams shut). Without them: stretch 1.2240 for one step
/// (a strap's particle slipping forward over the shoulder while its
/// neighbours stick), typically 1.0872, seams within 0.52 mm; the grid's
/// one-piece 1.423, 1.262, 1.414. With 6.5 cm straps cut straight and
/// the default sewing pull: 1.357, 1.148, 1.336 (the straps' inner edges
/// carried the dress); the wider tapered straps alone: 1.489 while sewn,
/// a seam 17 mm open at 0.6 s; with 0.35 and 0.5 N of sewing pull instead
/// of 0.75: 1.234 and 1.297, seams within 0.57 and 3.75 mm. Before a
/// stitched point counted as one for self-collision the four waist-corner
/// stitches, where each waist seam meets two side seams, stayed 5 mm
/// open: a skirt corner was repelled by the bodice corner it is sewn to
/// through a side seam.
#[test]
#[ignore = "slow tier: cargo test --release -- --ignored"]
fn the_pattern_dress_stays_on_the_walking_mannequin() {
    let worn = wear("pattern-dress-walk.toml", "torso", &[]);
    worn.assert_stays_on(1.101, 0.45, [-0.65, 0.55]);
    worn.assert_sewn(1e-9, 1.109, 1.08);
}
