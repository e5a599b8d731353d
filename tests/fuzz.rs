//! The readers against malformed input: every fixture scene, OBJ and glTF
//! mesh, URDF rig and BVH motion, mutated many ways (characters changed, cut
//! short, lines dropped, doubled or swapped, numbers replaced by NaN,
//! infinities, 1e308, negatives), must be read into a value or refused
//! with an error. None may panic.

use cloth_core::scene::Scene;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

/// xorshift64*: a fixed sequence, so a failure replays.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const NUMBERS: [&str; 10] = ["nan", "inf", "-inf", "1e308", "-1e308", "-1", "0", "1e-320", "99999999999", ""];

/// One mutation of `text`.
fn mutate(text: &str, rng: &mut Rng) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        return String::new();
    }
    let k = rng.below(lines.len());
    match rng.below(6) {
        0 => {
            let chars: Vec<char> = lines[k].chars().collect();
            if !chars.is_empty() {
                let at = rng.below(chars.len());
                let new = b"=[]{}\",.-09eE#x \t"[rng.below(17)] as char;
                lines[k] = chars[..at].iter().chain(std::iter::once(&new)).chain(&chars[at + 1..]).collect();
            }
        }
        1 => {
            let keep: String = text.chars().take(rng.below(text.chars().count())).collect();
            return keep;
        }
        2 => {
            lines.remove(k);
        }
        3 => {
            let copy = lines[k].clone();
            lines.insert(k, copy);
        }
        4 => {
            // The first number-like token of the line, replaced.
            let line = &lines[k];
            if let Some(start) = line.find(|c: char| c.is_ascii_digit()) {
                let end = line[start..]
                    .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
                    .map_or(line.len(), |e| start + e);
                lines[k] = format!("{}{}{}", &line[..start], NUMBERS[rng.below(NUMBERS.len())], &line[end..]);
            }
        }
        _ => {
            let j = rng.below(lines.len());
            lines.swap(k, j);
        }
    }
    lines.join("\n")
}

fn fixtures(dir: &str, ext: &str) -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures").join(dir);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    files
}

/// Feeds `rounds` mutations of each file to `read`; returns the inputs
/// that panicked (file, round).
fn panics(files: &[PathBuf], rounds: usize, read: impl Fn(&str, &Path)) -> Vec<(PathBuf, usize)> {
    let mut found = Vec::new();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for file in files {
        let text = std::fs::read_to_string(file).unwrap();
        for round in 0..rounds {
            let input = mutate(&text, &mut rng);
            if catch_unwind(AssertUnwindSafe(|| read(&input, file))).is_err() {
                found.push((file.clone(), round));
            }
        }
    }
    found
}

/// Runs `f` with panics (caught and counted by the tests) printed as one
/// short line each, then puts the default report back.
fn with_short_panic_messages<T>(f: impl FnOnce() -> T) -> T {
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|info| eprintln!("panic: {info}")));
    let out = f();
    std::panic::set_hook(default_hook);
    out
}

#[test]
fn malformed_inputs_are_refused_never_panic() {
    let (scenes, objs, rigs, motions) = with_short_panic_messages(malformed_inputs);
    for (what, found) in [("scenes", &scenes), ("OBJ and glTF", &objs), ("URDF", &rigs), ("BVH", &motions)] {
        println!("{what}: {} panics", found.len());
    }
    assert!(
        scenes.is_empty() && objs.is_empty() && rigs.is_empty() && motions.is_empty(),
        "{scenes:?} {objs:?} {rigs:?} {motions:?}"
    );
}

type Panics = Vec<(PathBuf, usize)>;

/// Every fixture scene, OBJ, URDF and BVH mutated, read: the inputs that panicked.
fn malformed_inputs() -> (Panics, Panics, Panics, Panics) {
    let scenes = panics(&fixtures("scenes", "toml"), 200, |text, _| {
        if let Ok(scene) = Scene::parse(text, &[]) {
            // Keep a mutated grid or pattern small: the readers are under
            // test, not the builder's speed (a pattern's bound is 4e6
            // triangles; six of them near it took the machine's memory).
            let pattern_triangles = |piece: &cloth_core::PatternPiece| {
                let (lo, hi) = piece.outline_m.iter().fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), p| {
                    ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
                });
                (hi[0] - lo[0]) * (hi[1] - lo[1]) / (0.4 * piece.edge_length_m * piece.edge_length_m)
            };
            let small = scene.panels.iter().all(|p| p.particles[0] * p.particles[1] <= 20_000)
                && scene.meshes.iter().filter_map(|m| m.pattern.as_ref()).all(|p| pattern_triangles(p) <= 20_000.0);
            if small {
                let _ = scene.build();
            }
        }
    });
    let objs = panics(&fixtures("meshes", "obj"), 1000, |text, _| {
        let _ = cloth_collide::parse_obj(text);
    });
    let gltfs = gltf_panics(&fixtures("meshes", "glb"), 1000);
    let rigs = panics(&fixtures("rigs", "urdf"), 500, |text, file| {
        let _ = cloth_rapier::rig::Rig::parse(text, file, Default::default());
    });
    let motions = panics(&fixtures("motions", "bvh"), 2000, |text, file| {
        let _ = cloth_rapier::bvh::Bvh::parse(text, file);
    });
    (scenes, [objs, gltfs].concat(), rigs, motions)
}

/// Each `.glb` fixture mutated `rounds` times, read: its JSON chunk
/// mutated as text (the chunk's length kept right), or bytes anywhere set
/// to random values, or the file cut short. The inputs that panicked.
fn gltf_panics(files: &[PathBuf], rounds: usize) -> Panics {
    let mut found = Vec::new();
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    for file in files {
        let bytes = std::fs::read(file).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let json = std::str::from_utf8(&bytes[20..20 + json_len]).unwrap();
        for round in 0..rounds {
            let input = match rng.below(3) {
                0 => {
                    let mut text = mutate(json, &mut rng).into_bytes();
                    text.resize(text.len().next_multiple_of(4), b' ');
                    let rest = &bytes[20 + json_len..];
                    let total = (20 + text.len() + rest.len()) as u32;
                    let mut out = [&b"glTF"[..], &2u32.to_le_bytes(), &total.to_le_bytes()].concat();
                    out.extend((text.len() as u32).to_le_bytes());
                    out.extend(b"JSON");
                    out.extend(text);
                    out.extend(rest);
                    out
                }
                1 => {
                    let mut out = bytes.clone();
                    for _ in 0..1 + rng.below(4) {
                        let at = rng.below(out.len());
                        out[at] = rng.next() as u8;
                    }
                    out
                }
                _ => bytes[..rng.below(bytes.len())].to_vec(),
            };
            let read = || cloth_collide::parse_gltf(&input, file, None);
            if catch_unwind(AssertUnwindSafe(read)).is_err() {
                found.push((file.clone(), round));
            }
        }
    }
    found
}

/// Random pattern outlines (3 to 12 corners anywhere in a square, so
/// often self-crossing; repeated, collinear and nearly coincident corners;
/// lines inside and out; edge lengths from far too fine to coarser than
/// the piece) are meshed or refused, never a panic, and what is meshed is
/// a mesh the model takes: consistently wound, manifold, every vertex used.
#[test]
fn random_pattern_outlines_are_meshed_or_refused() {
    use cloth_core::{MeshPanel, PatternPiece};
    let mut rng = Rng(0x5eed_0f9a_77e2);
    let unit = |rng: &mut Rng| (rng.next() >> 11) as f64 / (1u64 << 53) as f64;
    let (mut meshed, mut refused, mut triangulator) = (0, 0, 0);
    with_short_panic_messages(|| {
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
            };
            let result =
                catch_unwind(AssertUnwindSafe(|| MeshPanel::from_pattern(piece.clone()).resolve(Path::new("."))));
            match result {
                Err(_) => panic!("round {round}: meshing panicked on {piece:?}"),
                Ok(Ok(mesh)) => {
                    assert!(mesh.check().is_ok(), "round {round}");
                    meshed += 1;
                }
                Ok(Err((_, why))) => {
                    refused += 1;
                    triangulator += usize::from(why.contains("triangulator"));
                }
            }
        }
    });
    println!("{meshed} meshed, {refused} refused ({triangulator} by the triangulator's own panic, caught)");
    assert!(meshed > 100 && refused > 100, "{meshed} meshed, {refused} refused: the cases miss one side");
}
