//! The shape of the code (docs/architecture.md), checked: the module graph of the library has no
//! cycle, the layers are used one way (twin <- method <- replay <- campaign), the library has no
//! command line in it, and the method's stages cannot read the simulation's truth.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every library source file (the binary's `main.rs` and `cli/` are not the library).
fn library_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                if path.file_name().unwrap() != "cli" {
                    walk(&path, out);
                }
            } else if path.extension().is_some_and(|e| e == "rs")
                && path.file_name().unwrap() != "main.rs"
            {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), &mut out);
    out.sort();
    out
}

/// The module path of a file: `src/method/trial.rs` -> `["method", "trial"]`.
fn module_of(file: &Path) -> Vec<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let rel = file.strip_prefix(&src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The library's code without comments (line comments only; the crate has no block comments in
/// code) and without its unit tests (a file's `#[cfg(test)] mod tests`, always last, whose
/// `super::` is the file itself).
fn code(file: &Path) -> String {
    let text = std::fs::read_to_string(file).unwrap();
    let library = text.split("#[cfg(test)]").next().unwrap();
    library
        .lines()
        .map(|l| l.split("//").next().unwrap())
        .collect::<Vec<_>>()
        .join("\n")
}

/// Expands a use tree such as `a::{b, c::{d, e}}` into `a::b`, `a::c::d`, `a::c::e`.
fn expand(tree: &str) -> Vec<String> {
    let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(open) = tree.find('{') else {
        return vec![tree];
    };
    let (prefix, rest) = (&tree[..open], &tree[open + 1..tree.len() - 1]);
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (i, ch) in rest.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&rest[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&rest[start..]);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(|p| expand(&format!("{prefix}{p}")))
        .collect()
}

/// Every path written inline from `root` (`crate::` or `super::`): `crate::a::B` in an
/// expression or a type, `super::x::f()`, `super::super::y` (taken whole, from its first
/// `super`).
fn inline_paths(text: &str, root: &str) -> Vec<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    for (at, _) in text.match_indices(root) {
        if at > 0 && (bytes[at - 1].is_ascii_alphanumeric() || matches!(bytes[at - 1], b'_' | b':'))
        {
            continue;
        }
        let end = text[at..]
            .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
            .map_or(text.len(), |e| at + e);
        out.push(text[at..end].trim_end_matches(':').to_string());
    }
    out
}

/// The paths the code `text` of module `me` names through `crate::` and `super::`, in `use`
/// trees and inline, made absolute.
fn referenced_paths(me: &[String], text: &str) -> Vec<Vec<String>> {
    let mut raw = Vec::new();
    for stmt in text.split(';') {
        if let Some(at) = stmt.find("use ") {
            let tree = stmt[at + 4..].trim();
            if tree.starts_with("crate::") || tree.starts_with("super::") {
                raw.extend(expand(tree));
            }
        }
    }
    raw.extend(inline_paths(text, "crate::"));
    raw.extend(inline_paths(text, "super::"));
    raw.into_iter()
        .filter_map(|p| {
            let segs: Vec<String> = p.split("::").map(String::from).collect();
            match segs[0].as_str() {
                "crate" => Some(segs[1..].to_vec()),
                "super" => {
                    let mut base = me[..me.len() - 1].to_vec();
                    let mut rest = &segs[1..];
                    while rest.first().is_some_and(|s| s == "super") {
                        base.pop();
                        rest = &rest[1..];
                    }
                    base.extend(rest.iter().cloned());
                    Some(base)
                }
                _ => None,
            }
        })
        .collect()
}

type Graph = BTreeMap<String, BTreeSet<String>>;

/// Module -> the modules it names (the longest module prefix of each path), itself and its
/// ancestors excluded, from each module's path and code.
fn graph_of(sources: &[(Vec<String>, String)]) -> Graph {
    let modules: BTreeSet<&Vec<String>> = sources.iter().map(|(m, _)| m).collect();
    let mut graph = BTreeMap::new();
    for (me, text) in sources {
        let deps: BTreeSet<String> = referenced_paths(me, text)
            .into_iter()
            .filter_map(|p| {
                (1..=p.len())
                    .rev()
                    .map(|n| p[..n].to_vec())
                    .find(|m| modules.contains(m))
            })
            .filter(|m| m != me && !me.starts_with(m))
            .map(|m| m.join("::"))
            .collect();
        graph.insert(me.join("::"), deps);
    }
    graph
}

/// The library's module graph.
fn module_graph() -> Graph {
    let sources: Vec<(Vec<String>, String)> = library_files()
        .iter()
        .map(|f| (module_of(f), code(f)))
        .collect();
    graph_of(&sources)
}

/// The first cycle of `graph` (depth-first search with colours), as its modules in order.
fn find_cycle(graph: &Graph) -> Option<Vec<String>> {
    fn visit<'a>(
        m: &'a str,
        graph: &'a Graph,
        state: &mut BTreeMap<&'a str, u8>,
        stack: &mut Vec<&'a str>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(2) => return None,
            Some(1) => {
                let from = stack.iter().position(|s| *s == m).unwrap();
                let mut cycle: Vec<String> = stack[from..].iter().map(|s| s.to_string()).collect();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(m, 1);
        stack.push(m);
        for d in graph.get(m).into_iter().flatten() {
            if let Some(c) = visit(d, graph, state, stack) {
                return Some(c);
            }
        }
        stack.pop();
        state.insert(m, 2);
        None
    }
    let mut state = BTreeMap::new();
    graph
        .keys()
        .find_map(|m| visit(m, graph, &mut state, &mut Vec::new()))
}

#[test]
fn the_module_graph_has_no_cycle() {
    let graph = module_graph();
    assert!(graph.len() > 30, "found {} modules", graph.len());
    let cycle = find_cycle(&graph);
    assert!(
        cycle.is_none(),
        "import cycle: {}",
        cycle.unwrap().join(" -> ")
    );
}

#[test]
fn a_circle_made_only_of_inline_paths_is_found() {
    let module = |path: &str, code: &str| {
        let path = path.split("::").map(String::from).collect();
        (path, code.to_string())
    };
    // As `geometry::mesh` and `geometry::stack` were: neither has a `use` of the other.
    let mut sources = vec![
        module("twin::geometry", "pub mod mesh; pub mod stack;"),
        module(
            "twin::geometry::mesh",
            "fn f(s: &Soup) { let p = super::stack::cut(s); }",
        ),
        module(
            "twin::geometry::stack",
            "pub fn cut(s: &super::mesh::Soup) -> Vec<crate::twin::geometry::P3> { todo!() }",
        ),
    ];
    let cycle = find_cycle(&graph_of(&sources)).expect("the circle is found");
    assert_eq!(cycle.len(), 3, "{cycle:?}");
    assert!(cycle.contains(&"twin::geometry::mesh".to_string()));
    assert!(cycle.contains(&"twin::geometry::stack".to_string()));
    // Through `crate::` and two levels of `super::` as well; and gone once one side is cut.
    sources.push(module(
        "twin::workcell",
        "fn g() { super::super::twin::geometry::mesh::f(); }",
    ));
    sources[1].1 = "fn f() -> crate::twin::workcell::WorkCell { todo!() }".into();
    let cycle = find_cycle(&graph_of(&sources)).expect("the longer circle is found");
    assert!(cycle.contains(&"twin::workcell".to_string()), "{cycle:?}");
    sources[1].1 = "fn f() {}".into();
    assert_eq!(find_cycle(&graph_of(&sources)), None);
}

#[test]
fn the_layers_are_used_one_way() {
    let layer = |m: &str| match m.split("::").next().unwrap() {
        "twin" => 1,
        "method" => 2,
        "replay" | "selfcheck" => 3,
        "campaign" => 4,
        _ => 0,
    };
    for (m, deps) in module_graph() {
        for d in deps {
            assert!(
                layer(&d) <= layer(&m) || layer(&m) == 0 && m.is_empty(),
                "{m} (layer {}) uses {d} (layer {}): the layers are twin <- method <- replay, selfcheck <- campaign",
                layer(&m),
                layer(&d)
            );
        }
    }
}

#[test]
fn the_library_has_no_command_line_in_it() {
    for f in library_files() {
        let text = code(&f);
        for word in [
            "clap::",
            "indicatif",
            "println!",
            "eprintln!",
            "print!(",
            "std::process::exit",
        ] {
            assert!(!text.contains(word), "{} uses {word}", f.display());
        }
    }
}

#[test]
fn the_method_stages_cannot_read_the_truth() {
    for f in library_files() {
        let m = module_of(&f).join("::");
        // The trial sets the experiment up and scores it; the session records the trace; the
        // environment scores a learned policy and reports the truth beside (never as) its
        // observations. (The physics self-checks read the truth too: `selfcheck` is no stage.)
        let judges = ["method::trial", "method::session", "method::env"];
        if !m.starts_with("method") || judges.contains(&m.as_str()) {
            continue;
        }
        let text = code(&f);
        for word in [".truth()", "Truth", "true_contact", "base_t_hole()"] {
            assert!(
                !text.contains(word),
                "{m} reads the simulation's truth ({word})"
            );
        }
    }
}
