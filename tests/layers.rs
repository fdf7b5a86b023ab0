//! Imports inside `src/integrator/` run downward: the shared layer (the types of `mod.rs`,
//! `connection.rs`, `density.rs`, `mis.rs`, `subpath.rs`) names no technique, `pt.rs` and
//! `bpt.rs` name only the shared layer, `upg/` names no other technique, and only `vcm.rs`
//! names `upg/`. The technique is chosen above the integrators, in `render.rs`.

use std::path::Path;

const TECHNIQUES: [&str; 4] = ["pt", "bpt", "vcm", "upg"];

/// The file's code without its line comments.
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let lines: Vec<&str> = text
        .lines()
        .map(|line| line.split("//").next().unwrap_or(""))
        .collect();
    lines.join("\n")
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The first path segment of each item after each occurrence of `prefix` (`super::x`,
/// `super::{x, y::z}`), where `prefix` starts a path.
fn first_segments(code: &str, prefix: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (at, _) in code.match_indices(prefix) {
        if code[..at]
            .chars()
            .next_back()
            .is_some_and(|c| is_ident(c) || c == ':')
        {
            continue;
        }
        let rest = code[at + prefix.len()..].trim_start_matches("super::");
        let items = match rest.strip_prefix('{') {
            Some(group) => group.split('}').next().unwrap_or(""),
            None => rest,
        };
        for item in items.split(',') {
            let segment: String = item.trim().chars().take_while(|&c| is_ident(c)).collect();
            found.push(segment);
            if !rest.starts_with('{') {
                break;
            }
        }
    }
    found
}

/// The technique modules a file of `src/integrator/` names: `file` as `upg/merge.rs` or
/// `vcm.rs`.
fn named_techniques(file: &str, code: &str) -> Vec<&'static str> {
    let mut segments = first_segments(code, "crate::integrator::");
    if file == "mod.rs" {
        // Its children by bare paths (`vcm::VertexCm`); `pub mod vcm;` declares, not names.
        for module in TECHNIQUES {
            let bare = format!("{module}::");
            let by_path = code
                .match_indices(&bare)
                .any(|(at, _)| !code[..at].chars().next_back().is_some_and(is_ident));
            if by_path {
                segments.push(module.to_string());
            }
        }
    } else if let Some(inner) = file.strip_prefix("upg/") {
        // `super::` is upg/ itself (from upg/mod.rs, integrator/).
        let up = if inner == "mod.rs" {
            "super::"
        } else {
            "super::super::"
        };
        segments.extend(first_segments(code, up));
    } else {
        segments.extend(first_segments(code, "super::"));
    }
    TECHNIQUES
        .into_iter()
        .filter(|t| segments.iter().any(|s| s == t))
        .collect()
}

/// The techniques a file may name besides itself.
fn may_name(file: &str) -> &'static [&'static str] {
    match file {
        // One-stage merging is vcm's own pass (a child module of vcm.rs).
        "vcm.rs" | "onestage.rs" => &["upg"],
        f if f.starts_with("upg/") => &["upg"],
        _ => &[],
    }
}

#[test]
fn no_upward_arrow_inside_the_integrators() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/integrator");
    let mut files = Vec::new();
    for (dir, prefix) in [(root.clone(), ""), (root.join("upg"), "upg/")] {
        for entry in std::fs::read_dir(&dir).expect("src/integrator") {
            let path = entry.expect("a directory entry").path();
            if path.extension().is_some_and(|x| x == "rs") {
                let name = path.file_name().expect("a file name").to_string_lossy();
                files.push((format!("{prefix}{name}"), path));
            }
        }
    }
    assert!(files.len() >= 10, "found only {files:?}");
    let mut breaks = Vec::new();
    for (file, path) in &files {
        let own = file.trim_end_matches(".rs");
        for module in named_techniques(file, &code(path)) {
            if module != own && !may_name(file).contains(&module) {
                breaks.push(format!("{file} names {module}"));
            }
        }
    }
    assert!(breaks.is_empty(), "upward arrows: {breaks:#?}");
}

/// The check finds the arrows it is for.
#[test]
fn the_check_sees_an_arrow() {
    assert_eq!(
        named_techniques("subpath.rs", "use super::upg::Deferred;"),
        ["upg"]
    );
    assert_eq!(
        named_techniques("mis.rs", "use super::{connection, vcm::Modes};"),
        ["vcm"]
    );
    assert_eq!(
        named_techniques("mod.rs", "pub mod pt;\nfn f() { pt::PathTracer::new() }"),
        ["pt"]
    );
    assert_eq!(
        named_techniques(
            "upg/merge.rs",
            "use super::super::bpt::X; use super::acceptance;"
        ),
        ["bpt"]
    );
    assert!(named_techniques("mod.rs", "pub mod pt;\npub mod vcm;").is_empty());
    assert!(named_techniques("pt.rs", "use super::mis::Weights; let spt = 1;").is_empty());
}
