//! An FMU as a co-simulation unit: the cloth FMU and a native unit
//! co-simulated together by `cloth-cosim`'s masters, as the same cloth
//! unit native.

use cloth_cosim::oscillator::{MassUnit, Oscillator};
use cloth_cosim::{ClothUnit, CoSimulation, Connection, InputOverStep, IteratedParams, Master, Port, Unit};
use cloth_fmu::import::FmuUnit;
use std::path::{Path, PathBuf};

/// The hang fixture's cloth, 11 x 11, flat at z = 0, held at the middle
/// of one edge by one pin driven from outside.
const OVERRIDES: [&str; 5] = [
    "panels.0.particles=[11, 11]",
    "panels.0.origin_m=[-0.5, -0.5, 0.0]",
    "pins.0.nodes=[[5, 10]]",
    "pins.0.motion={ kind = \"external\" }",
    "solver.rel_tol=1e-10",
];

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/hang.toml")
}

fn overrides() -> Vec<String> {
    OVERRIDES.iter().map(|s| s.to_string()).collect()
}

/// This crate's shared library, where cargo put it for the tests.
fn library() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let deps = exe.parent().unwrap();
    [deps.join("libcloth_fmu.so"), deps.parent().unwrap().join("libcloth_fmu.so")]
        .into_iter()
        .find(|p| p.is_file())
        .expect("libcloth_fmu.so beside the test binary")
}

fn fmu(name: &str) -> PathBuf {
    let out = std::env::temp_dir().join(format!("cloth-fmu-import-{}-{name}.fmu", std::process::id()));
    cloth_fmu::build_fmu(&scene(), &overrides(), &library(), &out).unwrap();
    out
}

fn native() -> ClothUnit {
    cloth_fmu::package::unit_from_scene(&scene(), &overrides(), "cloth").unwrap()
}

/// The cloth hanging from a 0.5 kg mass on a 50 N/m spring (unit A of the
/// oscillator: input the force on it, output its position): the pin
/// follows the mass, the mass feels the pin's reaction.
fn spring_and_cloth(cloth: Box<dyn Unit>, master: Master) -> CoSimulation {
    let osc = Oscillator { m1: 0.5, k1: 50.0, ..Oscillator::default() };
    let mass = MassUnit::force_driven(&osc, 0.0, 10);
    let pin_z = cloth.find("pin0.target.z").unwrap();
    let reaction_z = cloth.find("pin0.reaction.z").unwrap();
    let (x1, force) = (mass.find("x1").unwrap(), mass.find("F").unwrap());
    let connections = vec![
        Connection { from: Port { unit: 1, var: x1 }, to: Port { unit: 0, var: pin_z } },
        Connection { from: Port { unit: 0, var: reaction_z }, to: Port { unit: 1, var: force } },
    ];
    CoSimulation::new(vec![cloth, Box::new(mass)], connections, master).unwrap()
}

#[test]
fn the_fmu_is_the_native_unit_under_every_master() {
    let path = fmu("masters");
    let h = 1.0 / 90.0;
    // FMI 3.0 co-simulation has no input derivatives; the cloth FMU takes
    // a pin's as the input its model description declares `derivative` of
    // the target, so the iterated master hands it the guess either as a
    // rate from the start value (linear) or as a value held over the step.
    let end_value = IteratedParams { inputs: InputOverStep::EndValue, ..IteratedParams::default() };
    let linear = IteratedParams { inputs: InputOverStep::Linear, ..IteratedParams::default() };
    for master in [Master::GaussSeidel(Default::default()), Master::Iterated(end_value), Master::Iterated(linear)] {
        let mut with_fmu = spring_and_cloth(Box::new(FmuUnit::load(&path, "cloth").unwrap()), master.clone());
        let mut with_native = spring_and_cloth(Box::new(native()), master.clone());
        let outputs = |c: &CoSimulation| -> Vec<u64> {
            (0..2)
                .flat_map(|u| {
                    let unit = c.unit(u);
                    (0..unit.variables().len()).map(move |v| unit.get(v).unwrap().to_bits()).collect::<Vec<_>>()
                })
                .collect()
        };
        for _ in 0..45 {
            with_fmu.step(h).unwrap();
            with_native.step(h).unwrap();
            assert_eq!(outputs(&with_fmu), outputs(&with_native), "{master:?}");
        }
        // The cloth's weight pulls the mass down its spring.
        let x1 = with_fmu.unit(1).get(with_fmu.unit(1).find("x1").unwrap()).unwrap();
        println!("{master:?}: the mass at {x1} m after 0.5 s");
        assert!(x1 < -0.005, "{x1}");
    }
}

#[test]
fn states_of_an_fmu_unit_replay_and_bad_files_are_refused() {
    let path = fmu("states");
    let mut unit = FmuUnit::load(&path, "cloth").unwrap();
    let h = 1.0 / 90.0;
    for n in 0..3 {
        unit.do_step(n as f64 * h, h).unwrap();
    }
    let state = unit.get_state();
    let bytes = unit.serialize_state(&state).unwrap();
    let run = |unit: &mut FmuUnit| -> Vec<u64> {
        for n in 3..6 {
            unit.do_step(n as f64 * h, h).unwrap();
        }
        (0..unit.variables().len()).map(|v| unit.get(v).unwrap().to_bits()).collect()
    };
    let first = run(&mut unit);
    unit.set_state(&state).unwrap();
    assert_eq!(run(&mut unit), first);
    let restored = unit.deserialize_state(&bytes).unwrap();
    unit.set_state(&restored).unwrap();
    assert_eq!(run(&mut unit), first);
    // Bytes that are not a state: refused with the FMU's own reason.
    let junk = unit.deserialize_state(&bytes[..bytes.len() / 2]).unwrap();
    let e = unit.set_state(&junk).unwrap_err().to_string();
    assert!(e.contains("not a serialised state"), "{e}");
    // An output cannot be set; the FMU's reason is in the error.
    let reaction = unit.find("pin0.reaction.z").unwrap();
    assert!(unit.set(reaction, 1.0).unwrap_err().to_string().contains("outputs cannot be set"));
    // Not an FMU.
    let scene_path = scene();
    assert!(FmuUnit::load(&scene_path, "x").is_err());
}

/// A scene with an OBJ solid: the mesh travels in the FMU (under
/// `resources/meshes/`) and the cloth drapes on it there as it does native.
#[test]
fn a_mesh_solid_travels_in_the_fmu() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/drape-mesh.toml");
    let overrides = vec!["panels.0.particles=[21, 21]".to_string()];
    let out = std::env::temp_dir().join(format!("cloth-fmu-import-{}-mesh.fmu", std::process::id()));
    let built = cloth_fmu::build_fmu(&scene, &overrides, &library(), &out).unwrap();
    let entries = cloth_fmu::package::read_fmu(&built.path).unwrap();
    let pillow = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes/pillow.obj")).unwrap();
    assert!(entries.iter().any(|(name, data)| name == "resources/meshes/0-pillow.obj" && *data == pillow));
    let mut fmu = FmuUnit::load(&built.path, "cloth").unwrap();
    let mut native = cloth_fmu::package::unit_from_scene(&scene, &overrides, "cloth").unwrap();
    let h = 1.0 / 90.0;
    for n in 0..30 {
        fmu.do_step(n as f64 * h, h).unwrap();
        native.do_step(n as f64 * h, h).unwrap();
    }
    let bits = |u: &dyn Unit| -> Vec<u64> { (0..u.variables().len()).map(|v| u.get(v).unwrap().to_bits()).collect() };
    assert_eq!(bits(&fmu), bits(&native));
    // The cloth has landed on the pillow and presses it down.
    let pressed = fmu.get(fmu.find("solid0.force.z").unwrap()).unwrap();
    assert!(pressed < -0.1, "{pressed} N");
}

/// The FMU repacked as other tools write archives: directory entries
/// before the files, the shared library stored and the rest deflated at
/// the highest level, an archive comment. It loads and steps bit for bit
/// as the FMU this crate wrote (which is deflated: smaller than its
/// library alone).
#[test]
fn an_archive_laid_out_as_other_tools_write_it_loads_and_steps_the_same() {
    let ours = fmu("ours");
    let entries = cloth_fmu::package::read_fmu(&ours).unwrap();
    let library_size = entries.iter().find(|(n, _)| n.starts_with("binaries/")).unwrap().1.len() as u64;
    let size = std::fs::metadata(&ours).unwrap().len();
    println!("FMU {size} bytes, its library {library_size} bytes");
    assert!(size < library_size, "the FMU is not compressed: {size} bytes");
    let theirs = std::env::temp_dir().join(format!("cloth-fmu-import-{}-theirs.fmu", std::process::id()));
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&theirs).unwrap());
    let stored = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    let deflated = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .compression_level(Some(9));
    for dir in ["binaries/", "binaries/x86_64-linux/", "resources/"] {
        zip.add_directory(dir, stored).unwrap();
    }
    for (name, data) in &entries {
        zip.start_file(name.as_str(), if name.starts_with("binaries/") { stored } else { deflated }).unwrap();
        std::io::Write::write_all(&mut zip, data).unwrap();
    }
    zip.set_comment("written by another tool").unwrap();
    zip.finish().unwrap();
    let (mut a, mut b) = (FmuUnit::load(&ours, "a").unwrap(), FmuUnit::load(&theirs, "b").unwrap());
    let h = 1.0 / 90.0;
    for n in 0..5 {
        a.do_step(n as f64 * h, h).unwrap();
        b.do_step(n as f64 * h, h).unwrap();
    }
    for v in 0..a.variables().len() {
        assert_eq!(a.get(v).unwrap().to_bits(), b.get(v).unwrap().to_bits(), "{}", a.variables()[v].name);
    }
}
