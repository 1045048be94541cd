//! Checks that keep the documentation true (rust-analyzer's `tidy` spirit): the crate edges
//! that docs/ARCHITECTURE.md lists are the `relief-*` `[dependencies]` of the manifests; and
//! size limits of issue 13 that keep the code readable: no source file of a crate or of xtask
//! over [`size::MAX_FILE_LINES`] lines (tests included), no function over
//! [`size::MAX_FN_LINES`] lines (tests aside).

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

#[cfg(test)]
mod size {
    use std::path::{Path, PathBuf};

    /// The most lines a source file under `crates/*/src` or `xtask/src` may have, its tests
    /// included (move a long `mod tests` into a sibling `tests.rs`).
    pub(super) const MAX_FILE_LINES: usize = 900;
    /// The most lines a function body may have, braces included (tests aside).
    pub(super) const MAX_FN_LINES: usize = 150;

    /// Functions still over the limit, as `path::name`, each with the reason it may stay for now.
    /// An entry that no longer needs to be here fails the test, so the list only shrinks.
    const KNOWN_LONG_FNS: &[(&str, &str)] = &[];

    /// Every `.rs` file below `dir`, sorted.
    fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                rust_files(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }

    /// The library, CLI and xtask sources: `crates/*/src/**.rs` and `xtask/src/**.rs`.
    fn sources(root: &Path) -> Vec<PathBuf> {
        let mut out = Vec::new();
        let mut crates: Vec<_> = std::fs::read_dir(root.join("crates"))
            .unwrap()
            .map(|e| e.unwrap().path().join("src"))
            .filter(|p| p.is_dir())
            .collect();
        crates.sort();
        crates.push(root.join("xtask/src"));
        for dir in crates {
            rust_files(&dir, &mut out);
        }
        out
    }

    /// A file that only holds a test module moved out of its parent
    /// (`#[cfg(test)] #[path = "foo_tests.rs"] mod tests;` or `foo/tests.rs`).
    fn is_test_file(path: &Path) -> bool {
        let name = path.file_stem().unwrap().to_string_lossy();
        name == "tests"
            || name.ends_with("_tests")
            || path.components().any(|c| c.as_os_str() == "tests")
    }

    /// The source with comments, string and character literals blanked out (newlines kept),
    /// so that braces can be matched on what is left.
    pub(super) fn code_only(src: &str) -> Vec<u8> {
        let s = src.as_bytes();
        let mut out = s.to_vec();
        let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
            for b in &mut out[from..to.min(s.len())] {
                if *b != b'\n' {
                    *b = b' ';
                }
            }
        };
        let ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
        let mut i = 0;
        while i < s.len() {
            let rest = &s[i..];
            if rest.starts_with(b"//") {
                let end = rest
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(s.len(), |n| i + n);
                blank(&mut out, i, end);
                i = end;
            } else if rest.starts_with(b"/*") {
                let (mut depth, mut j) = (0usize, i);
                while j < s.len() {
                    if s[j..].starts_with(b"/*") {
                        depth += 1;
                        j += 2;
                    } else if s[j..].starts_with(b"*/") {
                        depth -= 1;
                        j += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        j += 1;
                    }
                }
                blank(&mut out, i, j);
                i = j;
            } else if (i == 0 || !ident(s[i - 1]))
                && let Some(hashes) = raw_string_start(rest)
            {
                // r"..", r#".."#, br"..": ends at a quote followed by as many hashes.
                let open = rest.iter().position(|&b| b == b'"').unwrap() + 1;
                let mut j = i + open;
                while j < s.len() && !(s[j] == b'"' && s[j + 1..].starts_with(&hashes)) {
                    j += 1;
                }
                let end = j + 1 + hashes.len();
                blank(&mut out, i, end);
                i = end;
            } else if s[i] == b'"' {
                let mut j = i + 1;
                while j < s.len() && s[j] != b'"' {
                    j += if s[j] == b'\\' { 2 } else { 1 };
                }
                blank(&mut out, i, j + 1);
                i = j + 1;
            } else if s[i] == b'\'' {
                // A character literal ('x', '\n', '\u{7d}', a multi-byte char) or a lifetime.
                let len = src[i + 1..].chars().next().map_or(1, char::len_utf8);
                if rest.get(1) == Some(&b'\\') {
                    let j = i + 2 + s[i + 2..].iter().position(|&b| b == b'\'').unwrap();
                    blank(&mut out, i, j + 1);
                    i = j + 1;
                } else if s.get(i + 1 + len) == Some(&b'\'') {
                    blank(&mut out, i, i + 2 + len);
                    i += 2 + len;
                } else {
                    i += 1;
                }
            } else {
                i += 1;
            }
        }
        out
    }

    /// The hashes of a raw string opening at the start of `rest` (`r#"` -> `#`).
    fn raw_string_start(rest: &[u8]) -> Option<Vec<u8>> {
        let rest = rest.strip_prefix(b"b").unwrap_or(rest);
        let rest = rest.strip_prefix(b"r")?;
        let hashes: Vec<u8> = rest.iter().take_while(|&&b| b == b'#').copied().collect();
        (rest.get(hashes.len()) == Some(&b'"')).then_some(hashes)
    }

    /// The index of the brace closing the one at `open`.
    fn closing(code: &[u8], open: usize) -> usize {
        let mut depth = 0usize;
        for (j, &b) in code.iter().enumerate().skip(open) {
            match b {
                b'{' => depth += 1,
                b'}' => {
                    depth -= 1;
                    if depth == 0 {
                        return j;
                    }
                }
                _ => {}
            }
        }
        code.len() - 1
    }

    fn is_word_at(code: &[u8], i: usize, word: &[u8]) -> bool {
        let ident = |b: &u8| b.is_ascii_alphanumeric() || *b == b'_';
        code[i..].starts_with(word)
            && (i == 0 || !ident(&code[i - 1]))
            && !code.get(i + word.len()).is_some_and(ident)
    }

    /// `(name, first line, body lines)` of every function with a body outside
    /// `#[cfg(test)]` modules, the body counted from the line of its `{` to that of its `}`.
    pub(super) fn functions(src: &str) -> Vec<(String, usize, usize)> {
        let code = code_only(src);
        let line_of = |i: usize| code[..i].iter().filter(|&&b| b == b'\n').count() + 1;
        // Byte ranges of `#[cfg(test)] mod name { .. }`.
        let mut skip = Vec::new();
        let text = String::from_utf8_lossy(&code);
        for (at, _) in text.match_indices("#[cfg(test)]") {
            let after = text[at + 12..].trim_start();
            let after = after.strip_prefix("pub(crate) ").unwrap_or(after);
            if let Some(rest) = after.strip_prefix("mod ") {
                let start = code.len() - rest.len();
                let brace = rest.find(['{', ';']).map(|n| start + n);
                if let Some(b) = brace.filter(|&b| code[b] == b'{') {
                    skip.push(at..=closing(&code, b));
                }
            }
        }
        let mut out = Vec::new();
        for i in 0..code.len() {
            if !is_word_at(&code, i, b"fn") || skip.iter().any(|r| r.contains(&i)) {
                continue;
            }
            let name: String = text[i + 2..]
                .trim_start()
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if name.is_empty() {
                continue; // a `fn(..)` pointer type
            }
            // The body starts at the first `{` outside (), [] and <> brackets; a `;` there
            // ends a declaration without a body.
            let mut depth = 0i32;
            let mut body = None;
            for j in i + 2..code.len() {
                match code[j] {
                    b'(' | b'[' | b'<' => depth += 1,
                    b'>' if code[j - 1] == b'-' => {}
                    b')' | b']' | b'>' => depth -= 1,
                    b';' if depth <= 0 => break,
                    b'{' if depth <= 0 => {
                        body = Some(j);
                        break;
                    }
                    _ => {}
                }
            }
            if let Some(open) = body {
                let lines = line_of(closing(&code, open)) - line_of(open) + 1;
                out.push((name, line_of(i), lines));
            }
        }
        out
    }

    fn relative(root: &Path, path: &Path) -> String {
        path.strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/")
    }

    #[test]
    fn no_source_file_over_the_line_limit() {
        let root = crate::project_root();
        let mut long = Vec::new();
        for path in sources(&root) {
            let lines = std::fs::read_to_string(&path).unwrap().lines().count();
            if lines > MAX_FILE_LINES {
                long.push(format!("{} ({lines} lines)", relative(&root, &path)));
            }
        }
        assert!(
            long.is_empty(),
            "source files over {MAX_FILE_LINES} lines: {long:#?}\nsplit each into submodules by \
             responsibility, or move its `mod tests` into a sibling `tests.rs` file"
        );
    }

    #[test]
    fn no_function_over_the_line_limit() {
        let root = crate::project_root();
        let mut long = Vec::new();
        let mut known_seen = Vec::new();
        for path in sources(&root) {
            if is_test_file(&path) {
                continue;
            }
            let rel = relative(&root, &path);
            for (name, line, lines) in functions(&std::fs::read_to_string(&path).unwrap()) {
                let key = format!("{rel}::{name}");
                if lines <= MAX_FN_LINES {
                    continue;
                }
                if KNOWN_LONG_FNS.iter().any(|(k, _)| *k == key) {
                    known_seen.push(key);
                } else {
                    long.push(format!("{rel}:{line} fn {name} ({lines} lines)"));
                }
            }
        }
        assert!(
            long.is_empty(),
            "functions over {MAX_FN_LINES} lines: {long:#?}\nsplit each into named steps"
        );
        for (key, _) in KNOWN_LONG_FNS {
            assert!(
                known_seen.iter().any(|k| k == key),
                "{key} is no longer over {MAX_FN_LINES} lines: remove it from KNOWN_LONG_FNS in \
                 xtask/src/tidy.rs"
            );
        }
    }

    #[test]
    fn the_function_scanner_matches_braces_on_code_only() {
        let src = r##"
fn short<'a>(x: &'a str) -> impl Fn() -> char {
    let _ = "}}}"; let _ = '}'; let _ = r#"{"#; // }
    /* { */ move || '{'
}
trait T { fn decl(&self) -> [u8; 2]; }
#[cfg(test)]
mod tests {
    fn hidden() {}
}
fn generic<T: Into<f32>>(t: T) -> f32
where
    T: Copy,
{
    t.into()
}
"##;
        let found: Vec<_> = functions(src).into_iter().map(|(n, _, l)| (n, l)).collect();
        assert_eq!(
            found,
            [("short".to_string(), 4), ("generic".to_string(), 3)]
        );
    }
}

#[cfg(test)]
mod python_features {
    use std::collections::{BTreeMap, BTreeSet};
    use std::process::Command;

    /// Package -> features, as `cargo tree` resolves them for `args`.
    fn features(args: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
        let out = Command::new(env!("CARGO"))
            .args(["tree", "--offline", "--prefix", "none", "-f", "{p}|{f}"])
            .args(args)
            .current_dir(crate::project_root())
            .output()
            .expect("cargo tree");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let mut m: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            if let Some((p, f)) = line.trim_end_matches(" (*)").split_once('|') {
                m.entry(p.to_string())
                    .or_default()
                    .extend(f.split(',').filter(|x| !x.is_empty()).map(String::from));
            }
        }
        m
    }

    #[test]
    fn the_python_crate_resolves_the_workspace_features() {
        // maturin builds relief-python alone; with the features of `cargo test --workspace`
        // it reuses that build's library crates (crates/python/Cargo.toml says how).
        let py = features(&["-p", "relief-python", "-e", "normal,build"]);
        let ws = features(&["--workspace", "-e", "normal,build,dev"]);
        let differ: Vec<String> = py
            .iter()
            .filter(|(p, f)| ws.get(*p) != Some(f))
            .map(|(p, f)| format!("{p}: python {f:?}, workspace {:?}", ws.get(p)))
            .collect();
        assert!(
            differ.is_empty(),
            "add these features to crates/python/Cargo.toml:\n{}",
            differ.join("\n")
        );
    }
}
