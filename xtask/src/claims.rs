//! Tidy check that docs/ARCHITECTURE.md stays true: every file or folder it names in backticks
//! exists, and every Rust item it names (`a::b` paths, `CamelCase` types, `snake_case_names`)
//! is defined somewhere in the workspace's sources. A rename or a move that leaves the
//! document behind fails the test, naming the stale claim.

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;
    use std::path::{Path, PathBuf};

    /// Tokens the document uses as examples or as words of other tools, not as claims about
    /// this repository.
    const NOT_CLAIMS: &[&str] = &[
        "src/a.rs",
        "src/a/",
        "src/commands/<name>.rs",
        "tests/",
        "tests.rs",
        "spec.rs",
        "simplify.rs",
        "splat.png",
        "zstd-sys",
        "FILE.png.json",
        "manifest.json",
        // what the document says relief does not use, and a Rust attribute
        "StdRng",
        "tempfile::persist",
        "no_std",
    ];

    /// Every `.rs` and `.py` file below `dir` (skipping `target` and hidden folders).
    fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(rd) = std::fs::read_dir(dir) else {
            return;
        };
        for e in rd.flatten() {
            let p = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            if p.is_dir() {
                if name != "target" && !name.starts_with('.') {
                    sources(&p, out);
                }
            } else if name.ends_with(".rs") || name.ends_with(".py") {
                out.push(p);
            }
        }
    }

    /// The backticked tokens of `doc`.
    fn ticked(doc: &str) -> BTreeSet<String> {
        let mut out = BTreeSet::new();
        for (i, part) in doc.split('`').enumerate() {
            if i % 2 == 1 && !part.is_empty() && !part.contains('\n') {
                out.insert(part.to_string());
            }
        }
        out
    }

    /// A repository path: a `/` or a known file ending, no spaces, braces or placeholders.
    fn is_path(t: &str) -> bool {
        let plain = !t.contains([' ', '{', '}', '<', '>', '*', '(', '[', '=', ':', ','])
            && !t.starts_with('-')
            && !t.starts_with('.')
            && !t.starts_with('/');
        let ends = [".rs", ".py", ".md", ".toml", ".json", ".sh", "/"];
        plain && (t.contains('/') || ends.iter().any(|e| t.ends_with(e)))
    }

    /// A Rust item: `a::b::C`, a `CamelCase` word of two humps or more, or a
    /// `snake_case_name` with an underscore.
    fn item_name(t: &str) -> Option<&str> {
        let ident = |s: &str| {
            !s.is_empty()
                && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                && !s.starts_with(|c: char| c.is_ascii_digit())
        };
        if t.contains("::") {
            let segs: Vec<&str> = t.split("::").collect();
            return segs.iter().all(|s| ident(s)).then(|| *segs.last().unwrap());
        }
        if !ident(t) {
            return None;
        }
        let humps = t.chars().filter(|c| c.is_ascii_uppercase()).count();
        let camel = t.starts_with(|c: char| c.is_ascii_uppercase())
            && humps >= 2
            && t.len() >= 4
            && t.chars().any(|c| c.is_ascii_lowercase())
            && !t.contains('_');
        let snake = t.contains('_') && t.chars().all(|c| !c.is_ascii_uppercase());
        (camel || snake).then_some(t)
    }

    /// Whether `name` stands in `text` as a whole word (an item of a dependency the code uses,
    /// a dependency or feature of a manifest).
    fn used(name: &str, text: &str) -> bool {
        let word = |c: char| c.is_ascii_alphanumeric() || c == '_';
        text.match_indices(name)
            .any(|(i, _)| !text[..i].ends_with(word) && !text[i + name.len()..].starts_with(word))
    }

    /// Whether `name` is defined (as an item, a module, a field, a crate or a file stem) in
    /// `text`, the workspace's sources joined.
    fn defined(name: &str, text: &str) -> bool {
        let kinds = [
            "fn ",
            "struct ",
            "enum ",
            "trait ",
            "type ",
            "const ",
            "static ",
            "mod ",
            "def ",
            "class ",
            "macro_rules! ",
        ];
        kinds.iter().any(|k| text.contains(&format!("{k}{name}")))
            || text.contains(&format!(" {name}: "))
            || text.contains(&format!("    {name},"))
            || text.contains(&format!("    {name}("))
            || text.contains(&format!("    {name} {{"))
    }

    #[test]
    fn architecture_claims_are_true() {
        let root = crate::project_root();
        let doc = std::fs::read_to_string(root.join("docs/ARCHITECTURE.md")).unwrap();
        let mut files = Vec::new();
        for dir in ["crates", "xtask", "benches", "fuzz", "scripts"] {
            sources(&root.join(dir), &mut files);
        }
        let mut text = String::new();
        for m in std::fs::read_dir(root.join("crates")).unwrap().flatten() {
            text.push_str(
                &std::fs::read_to_string(m.path().join("Cargo.toml")).unwrap_or_default(),
            );
        }
        text.push_str(&std::fs::read_to_string(root.join("Cargo.toml")).unwrap_or_default());
        let mut stems = BTreeSet::new();
        for f in &files {
            text.push_str(&std::fs::read_to_string(f).unwrap_or_default());
            text.push('\n');
            if let Some(s) = f.file_stem() {
                stems.insert(s.to_string_lossy().replace('-', "_"));
            }
        }
        let mut crate_dirs: Vec<PathBuf> = std::fs::read_dir(root.join("crates"))
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .collect();
        crate_dirs.push(root.join("benches"));
        let mut stale = Vec::new();
        for t in ticked(&doc) {
            if NOT_CLAIMS.contains(&t.as_str()) {
                continue;
            }
            if is_path(&t) {
                let rel = t.trim_start_matches("../");
                let found = root.join(rel).exists()
                    || root.join("..").join(rel).exists()
                    || root.join("fixtures").join(rel).exists()
                    || crate_dirs
                        .iter()
                        .any(|c| c.join(rel).exists() || c.join("src").join(rel).exists())
                    || files.iter().any(|f| f.ends_with(rel));
                if !found {
                    stale.push(format!("path `{t}`"));
                }
            } else if let Some(name) = item_name(&t) {
                let crate_name = name.replace('-', "_");
                let is_crate = crate_name.starts_with("relief_")
                    && crate_dirs.iter().any(|c| {
                        std::fs::read_to_string(c.join("Cargo.toml")).is_ok_and(|m| {
                            m.contains(&format!("name = \"{}\"", t.replace('_', "-")))
                        })
                    });
                let own = t.starts_with("relief_") || t.starts_with("crate::");
                let known =
                    defined(name, &text) || stems.contains(name) || (!own && used(name, &text));
                if !is_crate && !known {
                    stale.push(format!("item `{t}`"));
                }
            }
        }
        assert!(
            stale.is_empty(),
            "docs/ARCHITECTURE.md names what does not exist (moved or renamed?): {}",
            stale.join(", ")
        );
    }

    #[test]
    fn the_claim_finder_sees_paths_and_items() {
        assert!(is_path("crates/io/src/geotiff.rs"));
        assert!(is_path("xtask/peers/"));
        assert!(!is_path("--max-time"));
        assert!(!is_path("{\"model\": \"paper\"}"));
        assert_eq!(item_name("relief_io::GeoTiffBands"), Some("GeoTiffBands"));
        assert_eq!(item_name("ParamError"), Some("ParamError"));
        assert_eq!(item_name("write_mesh"), Some("write_mesh"));
        assert_eq!(item_name("match"), None);
        assert_eq!(item_name("NaN"), None);
        assert!(defined("Thing", "pub struct Thing {"));
        assert!(!defined("Thing", "let thing = 1;"));
        assert!(used("serde_json", "use serde_json::Value;"));
        assert!(!used("serde_json", "use serde_json_ext::Value;"));
    }
}
