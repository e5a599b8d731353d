//! FMUs written by other tools, deflated as they ship, co-simulated with
//! the cloth: pythonfmu3 0.3.4 (FMI 3.0) and pythonfmu 0.7.0 (FMI 2.0),
//! each holding the hanging cloth's pin on a mass on a spring
//! (`fixtures/fmus/SpringMass{3,2}.py`, stepped by `spring_mass.py`
//! packed beside them), against the same mass as a native
//! unit. Both tools are installed by `.ci/run` beside FMPy
//! (`FMPY_PYTHON`); their binaries take Python's symbols from the host, so
//! `libpython` is preloaded and the embedded interpreter pointed at the
//! environment: the test runs itself again with `PYTHONHOME` and
//! `PYTHONPATH` set.

use cloth_cosim::oscillator::{MassUnit, Oscillator};
use cloth_cosim::{ClothUnit, CoSimulation, Connection, CosimError, IteratedParams, Master, Port, Unit, UnitError};
use cloth_fmu::import::{FmuUnit, LoadOptions, StartValue};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The hang fixture, 11 x 11, held at the middle of one edge by a pin
/// driven from outside.
fn cloth() -> ClothUnit {
    let overrides: Vec<String> = [
        "panels.0.particles=[11, 11]",
        "panels.0.origin_m=[-0.5, -0.5, 0.0]",
        "pins.0.nodes=[[5, 10]]",
        "pins.0.motion={ kind = \"external\" }",
        "solver.rel_tol=1e-10",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let scene = cloth_core::scene::Scene::parse_file(&root().join("fixtures/scenes/hang.toml"), &overrides).unwrap();
    let (model, cfg) = scene.build().unwrap();
    ClothUnit::new("cloth", cfg.simulation(model))
}

/// The cloth's pin follows the mass's position `x`; the mass feels the
/// pin's reaction as its force `F`.
fn held_by(mass: Box<dyn Unit>, x: &str, master: Master) -> Result<CoSimulation, CosimError> {
    let cloth = cloth();
    let (pin, reaction) = (cloth.find("pin0.target.z").unwrap(), cloth.find("pin0.reaction.z").unwrap());
    let (position, force) = (mass.find(x).unwrap(), mass.find("F").unwrap());
    let connections = vec![
        Connection { from: Port { unit: 1, var: position }, to: Port { unit: 0, var: pin } },
        Connection { from: Port { unit: 0, var: reaction }, to: Port { unit: 1, var: force } },
    ];
    CoSimulation::new(vec![Box::new(cloth), mass], connections, master)
}

/// The archive at `from` rewritten with every entry deflated.
fn deflated(from: &Path, to: &Path) {
    let mut archive = zip::ZipArchive::new(std::fs::File::open(from).unwrap()).unwrap();
    let mut out = zip::ZipWriter::new(std::fs::File::create(to).unwrap());
    let deflate = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for k in 0..archive.len() {
        let mut entry = archive.by_index(k).unwrap();
        let mut data = Vec::new();
        entry.read_to_end(&mut data).unwrap();
        out.start_file(entry.name().unwrap().to_string(), deflate).unwrap();
        out.write_all(&data).unwrap();
    }
    out.finish().unwrap();
    let mut check = zip::ZipArchive::new(std::fs::File::open(to).unwrap()).unwrap();
    assert!((0..check.len()).all(|k| check.by_index(k).unwrap().compression() == zip::CompressionMethod::Deflated));
}

#[test]
fn fmus_from_pythonfmu3_and_pythonfmu_hold_the_cloth() {
    let Some(python) = std::env::var_os("FMPY_PYTHON") else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must set FMPY_PYTHON (.ci/run installs pythonfmu3 and pythonfmu)"
        );
        println!("FMPY_PYTHON not set: the third-party FMU check did not run (see .ci/run)");
        return;
    };
    let query = "import os, sys, sysconfig; c = sysconfig.get_config_var; \
                 print(os.path.join(c('LIBDIR'), c('INSTSONAME'))); print(sys.base_prefix); \
                 print(sysconfig.get_paths()['purelib'])";
    let out = Command::new(&python).args(["-c", query]).output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let (libpython, home, site) = (PathBuf::from(lines[0]), lines[1], lines[2]);
    if std::env::var_os("PYTHONHOME").is_none() {
        let exe = std::env::current_exe().unwrap();
        let child = Command::new(exe)
            .args(["--exact", "fmus_from_pythonfmu3_and_pythonfmu_hold_the_cloth", "--nocapture", "--test-threads=1"])
            .env("PYTHONHOME", home)
            .env("PYTHONPATH", site)
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&child.stdout);
        println!("{said}");
        assert!(
            child.status.success() && said.contains("1 passed"),
            "{said}\n{}",
            String::from_utf8_lossy(&child.stderr)
        );
        return;
    }
    let bin = Path::new(&python).parent().unwrap();
    let work = std::env::temp_dir().join(format!("cloth-fmu-third-party-{}", std::process::id()));
    std::fs::create_dir_all(&work).unwrap();
    let h = 1.0 / 90.0;
    for (tool, model, version) in [("pythonfmu3", "SpringMass3", "3.0"), ("pythonfmu", "SpringMass2", "2.0")] {
        let script = root().join(format!("fixtures/fmus/{model}.py"));
        let step = root().join("fixtures/fmus/spring_mass.py");
        let built =
            Command::new(bin.join(tool)).arg("build").arg("-f").arg(&script).arg(&step).arg("-d").arg(&work).status();
        assert!(built.unwrap().success(), "{tool} build -f {}", script.display());
        let path = work.join(format!("{model}-deflated.fmu"));
        deflated(&work.join(format!("{model}.fmu")), &path);

        let options = LoadOptions {
            start_values: vec![
                ("m".into(), StartValue::Number(0.5)),
                ("label".into(), StartValue::Text("holds the cloth".into())),
            ],
            preload: vec![libpython.clone()],
        };
        let fmu = FmuUnit::load_with(&path, "mass", &options).unwrap();
        assert_eq!(fmu.fmi_version(), version);
        assert_eq!(fmu.string("label").unwrap(), "holds the cloth");
        let names: Vec<&str> = fmu.variables().iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["m", "k", "F", "x", "v", "steps", "moving"], "{tool}");

        // The native unit A of the oscillator is the same mass, integrated the same way.
        let osc = Oscillator { m1: 0.5, k1: 50.0, ..Oscillator::default() };
        let mut native =
            held_by(Box::new(MassUnit::force_driven(&osc, 0.0, 10)), "x1", Master::GaussSeidel(Default::default()))
                .unwrap();
        let mut with_fmu = held_by(Box::new(fmu), "x", Master::GaussSeidel(Default::default())).unwrap();
        let read = |c: &CoSimulation, u: usize, name: &str| {
            c.get(Port { unit: u, var: c.unit(u).find(name).unwrap() }).unwrap()
        };
        let mut gap: f64 = 0.0;
        for _ in 0..45 {
            native.step(h).unwrap();
            with_fmu.step(h).unwrap();
            gap = gap.max((read(&native, 1, "x1") - read(&with_fmu, 1, "x")).abs());
        }
        let x = read(&with_fmu, 1, "x");
        println!("{tool} ({version}): the mass at {x:.6} m after 0.5 s, {gap:.1e} m from the native unit");
        assert!(x < -0.005, "the cloth's weight pulls the mass down: {x}");
        assert!(gap < 1e-12, "{tool}: {gap} m from the native unit");
        assert_eq!((read(&with_fmu, 1, "steps"), read(&with_fmu, 1, "moving")), (45.0, 1.0));

        // Neither tool's FMU can go back to a state: the iterated master says so.
        let fmu = FmuUnit::load_with(&path, "mass", &options).unwrap();
        let mut iterated = held_by(Box::new(fmu), "x", Master::Iterated(IteratedParams::default())).unwrap();
        let e = iterated.step(h).unwrap_err().to_string();
        assert!(e.contains("cannot go back to a state"), "{tool}: {e}");
        let mut fmu = FmuUnit::load_with(&path, "mass", &options).unwrap();
        assert!(matches!(fmu.set(fmu.find("steps").unwrap(), 1.5), Err(UnitError::Causality { .. })));
        assert!(
            fmu.set_string("nothing", "x")
                .unwrap_err()
                .to_string()
                .contains("it has F, k, label, m, moving, steps, v, x")
        );
    }
    let _ = std::fs::remove_dir_all(&work);
}
