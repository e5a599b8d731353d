//! The house's rules, read off the sources: no import circles between
//! cloth-core's files, no source file of more than 800 lines besides its
//! tests, no error taken apart from its text, and each public item of
//! cloth-core by one path.
//!
//! A file imports another when it names an item only that other file
//! defines: in a `use`, in a path (`crate::laws::repulsion`), or as a
//! type (a capitalised name). Re-exports (`pub use`), comments, strings
//! and test modules are left out, and so are enum variants named like a
//! type elsewhere. It reads names, not Rust's resolution, so it errs
//! towards seeing an import: a circle it reports is there or close.

use regex::Regex;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the tests crate sits in the workspace").to_path_buf()
}

/// Every `.rs` file under `dir`, sorted.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// `text` without its first `#[cfg(test)] mod … { … }` and what follows
/// (test modules come last in this workspace's files).
fn before_tests(text: &str) -> &str {
    let tests = Regex::new(r"#\[cfg\(test\)\]\s*(pub(\([a-z]+\))?\s+)?mod\s+\w+\s*\{").unwrap();
    tests.find(text).map_or(text, |m| &text[..m.start()])
}

/// Whether a file (its path below the directory searched) is only tests.
fn is_test_file(path: &Path) -> bool {
    let name = path.file_name().unwrap().to_string_lossy();
    name == "tests.rs" || name.ends_with("_tests.rs") || path.components().any(|c| c.as_os_str() == "tests")
}

/// The code of `text`: no comments, no string contents, no test modules,
/// no re-exports.
fn code(text: &str) -> String {
    let comments = Regex::new(r"(?s)//[^\n]*|/\*.*?\*/").unwrap();
    let strings = Regex::new(r#""(\\.|[^"\\])*""#).unwrap();
    let reexports = Regex::new(r"(?m)^\s*pub(\([a-z]+\))?\s+use\b[^;]*;").unwrap();
    let text = comments.replace_all(text, "");
    let text = strings.replace_all(&text, "\"\"");
    let text = before_tests(&text).to_string();
    reexports.replace_all(&text, "").into_owned()
}

/// The file-level import graph of the crate rooted at `root`, lib.rs (the
/// facade) left out: file -> (file it imports -> the names that make it).
fn imports(root: &Path) -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let files: Vec<(String, String, String)> = sources(root)
        .into_iter()
        .filter(|p| !is_test_file(p.strip_prefix(root).unwrap()))
        .map(|p| {
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
            let stem = p.file_stem().unwrap().to_string_lossy().into_owned();
            (rel, stem, code(&std::fs::read_to_string(&p).unwrap()))
        })
        .filter(|(rel, ..)| rel != "lib.rs")
        .collect();
    let item =
        Regex::new(r"(?m)^(?:pub(?:\([a-z]+\))?\s+)?(?:const\s+fn|fn|struct|enum|trait|const|static|type)\s+(\w+)")
            .unwrap();
    let mut defined: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (rel, _, text) in &files {
        for c in item.captures_iter(text) {
            defined.entry(c[1].to_string()).or_default().insert(rel.clone());
        }
    }
    let modules: BTreeSet<String> = files
        .iter()
        .flat_map(|(rel, stem, _)| {
            let parent = Path::new(rel).parent().and_then(|p| p.file_name()).map(|n| n.to_string_lossy().into_owned());
            [Some(stem.clone()), parent].into_iter().flatten()
        })
        .collect();
    let unique: BTreeMap<&str, &str> = defined
        .iter()
        .filter(|(name, files)| files.len() == 1 && !modules.contains(*name))
        .map(|(name, files)| (name.as_str(), files.iter().next().unwrap().as_str()))
        .collect();
    let uses = Regex::new(r"(?m)^\s*use\b([^;]*);").unwrap();
    let word = Regex::new(r"\b[A-Za-z_]\w*\b").unwrap();
    let path = Regex::new(r"::\s*([A-Za-z_]\w*)").unwrap();
    let method = Regex::new(r"\.\s*[A-Za-z_]\w*").unwrap();
    let variant_path = Regex::new(r"\b([A-Z]\w*)::[A-Z]\w*").unwrap();
    let capitalised = Regex::new(r"\b[A-Z]\w*\b").unwrap();
    let variant = Regex::new(r"(?m)^\s+([A-Z][A-Za-z0-9]*)\s*(?:\(|\{|,|$)").unwrap();
    let mut graph = BTreeMap::new();
    for (rel, _, text) in &files {
        let mut names: BTreeSet<String> = BTreeSet::new();
        for u in uses.captures_iter(text) {
            names.extend(word.find_iter(&u[1]).map(|m| m.as_str().to_string()));
        }
        names.extend(path.captures_iter(text).map(|c| c[1].to_string()));
        let rest = method.replace_all(text, ".");
        let rest = variant_path.replace_all(&rest, "$1");
        names.extend(capitalised.find_iter(&rest).map(|m| m.as_str().to_string()));
        for v in variant.captures_iter(text) {
            names.remove(&v[1]);
        }
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for name in names {
            if let Some(&to) = unique.get(name.as_str())
                && to != rel
            {
                edges.entry(to.to_string()).or_default().insert(name);
            }
        }
        graph.insert(rel.clone(), edges);
    }
    graph
}

/// The strongly connected components of more than one file (Tarjan).
fn circles(graph: &BTreeMap<String, BTreeMap<String, BTreeSet<String>>>) -> Vec<Vec<String>> {
    struct Search<'g> {
        graph: &'g BTreeMap<String, BTreeMap<String, BTreeSet<String>>>,
        index: BTreeMap<&'g str, usize>,
        low: BTreeMap<&'g str, usize>,
        stack: Vec<&'g str>,
        on: BTreeSet<&'g str>,
        found: Vec<Vec<String>>,
    }
    impl<'g> Search<'g> {
        fn visit(&mut self, v: &'g str) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            self.on.insert(v);
            for w in self.graph[v].keys() {
                let w = w.as_str();
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let low = self.low[v].min(self.low[w]);
                    self.low.insert(v, low);
                } else if self.on.contains(w) {
                    let low = self.low[v].min(self.index[w]);
                    self.low.insert(v, low);
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on.remove(w);
                    component.push(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    self.found.push(component);
                }
            }
        }
    }
    let mut search = Search {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        found: Vec::new(),
    };
    for v in graph.keys() {
        if !search.index.contains_key(v.as_str()) {
            search.visit(v);
        }
    }
    search.found
}

#[test]
fn cloth_core_has_no_import_circles() {
    let graph = imports(&workspace().join("crates/cloth-core/src"));
    let edges: usize = graph.values().map(|e| e.len()).sum();
    println!("{} files, {edges} imports between them", graph.len());
    let found = circles(&graph);
    for component in &found {
        println!("a circle of {} files:", component.len());
        for a in component {
            for (b, names) in &graph[a] {
                if component.contains(b) {
                    println!("  {a} -> {b} {names:?}");
                }
            }
        }
    }
    assert!(graph.len() > 50 && edges > 200, "the sources were not read");
    assert!(found.is_empty(), "{} import circles (printed above)", found.len());
}

/// The checker sees a circle where there is one: two files that name each
/// other's items.
#[test]
fn the_circle_checker_finds_a_circle() {
    let dir = std::env::temp_dir().join(format!("cloth-architecture-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("a")).unwrap();
    std::fs::write(dir.join("a/one.rs"), "use crate::two::Two;\npub struct One(Two);\n").unwrap();
    std::fs::write(dir.join("a/two.rs"), "pub struct Two;\nimpl Two { fn f(_: &crate::one::One) {} }\n").unwrap();
    std::fs::write(dir.join("a/three.rs"), "use crate::two::Two;\npub fn three(_: Two) {}\n").unwrap();
    let found = circles(&imports(&dir));
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(found, vec![vec!["a/one.rs".to_string(), "a/two.rs".to_string()]]);
}

#[test]
fn no_source_file_has_more_than_800_lines_besides_its_tests() {
    let root = workspace();
    let mut largest = (0, PathBuf::new());
    let mut over = Vec::new();
    for dir in ["crates", "tools/src", "python/src", "benches"] {
        for path in sources(&root.join(dir)).into_iter().filter(|p| !is_test_file(p.strip_prefix(&root).unwrap())) {
            let text = std::fs::read_to_string(&path).unwrap();
            let lines = before_tests(&text).lines().count();
            if lines > largest.0 {
                largest = (lines, path.clone());
            }
            if lines > 800 {
                over.push((lines, path));
            }
        }
    }
    println!("largest: {} lines, {}", largest.0, largest.1.display());
    assert!(largest.0 > 300, "the sources were not read");
    assert!(over.is_empty(), "files over 800 lines besides tests: {over:?}");
}

/// An error names its field in a typed value ([`cloth_core::FieldError`],
/// an enum's variant), so no code reads one back out of the error's text:
/// no `split_once(": ")` on a message, no `contains` on an error string.
#[test]
fn no_error_is_read_back_from_its_text() {
    let root = workspace();
    let parsing = Regex::new(r#"split_once\(": "\)|\b(e|err|error|why)\.contains\("#).unwrap();
    let mut found = Vec::new();
    let mut files = 0;
    for dir in ["crates", "tools/src", "python/src"] {
        for path in sources(&root.join(dir)).into_iter().filter(|p| !is_test_file(p.strip_prefix(&root).unwrap())) {
            let text = std::fs::read_to_string(&path).unwrap();
            files += 1;
            for (k, line) in before_tests(&text).lines().enumerate() {
                if parsing.is_match(line) {
                    found.push(format!("{}:{}: {}", path.display(), k + 1, line.trim()));
                }
            }
        }
    }
    assert!(files > 100, "the sources were not read");
    assert!(found.is_empty(), "errors read back from their text:\n{}", found.join("\n"));
}

/// cloth-core's public modules are the laws, the force-term interface,
/// the scene files and (feature `testing`) the tests' internals; every
/// other item is re-exported at the root from a private module, so no
/// item has two paths. A module is a name with a file (`laws.rs`,
/// `terms/mod.rs`) in the crate.
#[test]
fn each_public_item_of_cloth_core_has_one_path() {
    let src = workspace().join("crates/cloth-core/src");
    let modules: BTreeSet<String> = sources(&src)
        .iter()
        .map(|p| {
            let stem = p.file_stem().unwrap().to_string_lossy().to_string();
            if stem == "mod" { p.parent().unwrap().file_name().unwrap().to_string_lossy().to_string() } else { stem }
        })
        .collect();
    let lib = code(&std::fs::read_to_string(src.join("lib.rs")).unwrap());
    let text = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    let declared = Regex::new(r"(?m)^\s*pub mod (\w+);").unwrap();
    let reexport = Regex::new(r"(?m)^pub use ([^;]+);").unwrap();
    let name = Regex::new(r"\b(\w+)\b").unwrap();
    let mut public: BTreeSet<String> = declared.captures_iter(&lib).map(|c| c[1].to_string()).collect();
    let mut items_from = Vec::new();
    for c in reexport.captures_iter(&text) {
        let path = c[1].to_string();
        // `a::b::{c, d}` or `a::b::c`: the names come from module `b`.
        let (prefix, list) = match path.split_once('{') {
            Some((prefix, list)) => (prefix.trim_end_matches("::"), list),
            None => path.rsplit_once("::").unwrap_or(("", &path)),
        };
        let from = prefix.rsplit("::").next().unwrap_or("");
        for n in name.captures_iter(list).map(|n| n[1].to_string()) {
            assert!(n != "self", "a module and its items both at the root: pub use {path}");
            if modules.contains(&n) {
                public.insert(n);
            } else {
                items_from.push((from.to_string(), n));
            }
        }
    }
    let expected = ["aero_laws", "contact_laws", "element_laws", "laws", "scene", "terms", "testing"];
    assert_eq!(public, expected.iter().map(|s| s.to_string()).collect(), "cloth-core's public modules");
    assert!(items_from.len() > 50, "the root's re-exports were not read");
    let twice: Vec<_> = items_from.iter().filter(|(from, _)| public.contains(from)).collect();
    assert!(twice.is_empty(), "items both in a public module and at the root: {twice:?}");
}
