//! Checks that keep the documentation true (rust-analyzer's `tidy` spirit): the crate edges
//! that docs/ARCHITECTURE.md lists are the `relief-*` `[dependencies]` of the manifests.

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, BTreeSet};
    use std::path::Path;

    /// The library crates "all of the above" stands for.
    const LIBS: &[&str] = &[
        "heightfield",
        "io",
        "sparse-core",
        "dictionary-learning",
        "wavelet-lod",
        "patch-synth",
        "implicit-volume",
    ];

    /// `relief-*` names (without the prefix) in a manifest section (`dependencies`,
    /// `dev-dependencies`).
    fn deps(manifest: &Path, section: &str) -> BTreeSet<String> {
        let text = std::fs::read_to_string(manifest).unwrap();
        let mut in_section = false;
        let mut out = BTreeSet::new();
        for line in text.lines() {
            let line = line.trim();
            if line.starts_with('[') {
                in_section = line == format!("[{section}]");
                continue;
            }
            if in_section && let Some(rest) = line.strip_prefix("relief-") {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                    .collect();
                out.insert(name);
            }
        }
        out
    }

    /// The edges listed in the first code block under "## Dependency edges".
    fn documented(root: &Path) -> BTreeMap<String, BTreeSet<String>> {
        let doc = std::fs::read_to_string(root.join("docs/ARCHITECTURE.md")).unwrap();
        let section = doc
            .split("## Dependency edges")
            .nth(1)
            .expect("docs/ARCHITECTURE.md has a `## Dependency edges` section");
        let block = section.split("```").nth(1).expect("a code block");
        let mut edges = BTreeMap::new();
        for line in block.lines() {
            let Some((name, rhs)) = line.split_once("->") else {
                continue;
            };
            let name = name.trim();
            if name.contains(',') {
                continue; // `tests, benches -> whatever they test`
            }
            // Drop the trailing `(comment)` (two or more spaces before it).
            let rhs = rhs.split("  (").next().unwrap().trim();
            let mut set = BTreeSet::new();
            for item in rhs.split(',').map(str::trim) {
                if item == "all of the above" {
                    set.extend(LIBS.iter().map(|s| s.to_string()));
                } else {
                    set.insert(item.to_string());
                }
            }
            edges.insert(name.to_string(), set);
        }
        edges
    }

    fn manifest(root: &Path, name: &str) -> std::path::PathBuf {
        match name {
            "xtask" | "benches" | "tests" => root.join(name).join("Cargo.toml"),
            _ => root.join("crates").join(name).join("Cargo.toml"),
        }
    }

    #[test]
    fn architecture_edges_match_the_manifests() {
        let root = crate::project_root();
        let doc = documented(&root);
        assert!(doc.len() >= 9, "{doc:?}");
        for (name, listed) in &doc {
            let actual = deps(&manifest(&root, name), "dependencies");
            assert_eq!(
                &actual, listed,
                "docs/ARCHITECTURE.md lists the edges of `{name}` as {listed:?}, its Cargo.toml \
                 has {actual:?}: update one of them"
            );
        }
        // Every crate folder is listed; `heightfield` has no relief dependency.
        for entry in std::fs::read_dir(root.join("crates")).unwrap() {
            let name = entry.unwrap().file_name().to_string_lossy().into_owned();
            if name == "heightfield" {
                assert!(deps(&manifest(&root, &name), "dependencies").is_empty());
            } else {
                assert!(
                    doc.contains_key(&name),
                    "crates/{name} is not in the edge list"
                );
            }
        }
        // The test-data locator is never a normal dependency of a library crate.
        for lib in LIBS {
            assert!(!deps(&manifest(&root, lib), "dependencies").contains("testdata"));
        }
    }
}
