//! Module cycles (tidy): within each crate, the top-level modules (`src/a.rs`, `src/a/`) and
//! the edges `a -> b` when a file of `a` names `crate::b` (or, at the top level, `super::b`).
//! A set of modules that reach each other is a knot a newcomer cannot read in one order. The
//! knots that exist are listed in [`KNOWN`] with the crate; a new knot, or a known one that
//! grew, fails the test, and a listed knot that is gone must be removed from the list, so the
//! list only shrinks.

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, BTreeSet};
    use std::path::{Path, PathBuf};

    /// The knots of today, `crate: [modules]`; each may only shrink or go.
    const KNOWN: &[(&str, &[&str])] = &[];

    /// Every `.rs` file below `dir`.
    fn files(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(rd) = std::fs::read_dir(dir) else {
            return;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                files(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }

    /// The top-level module a file of `src` belongs to (`None`: the crate root).
    fn module_of(src: &Path, file: &Path) -> Option<String> {
        let rel = file.strip_prefix(src).ok()?;
        let first = rel
            .components()
            .next()?
            .as_os_str()
            .to_string_lossy()
            .into_owned();
        let name = first.strip_suffix(".rs").unwrap_or(&first).to_string();
        (!["lib", "main"].contains(&name.as_str())).then_some(name)
    }

    /// The modules of `names` a line names through `crate::` (or `super::` in a top-level
    /// file, whose parent is the crate root), including `use crate::{a, b::c}` groups.
    fn named(line: &str, names: &BTreeSet<String>, top_level: bool) -> BTreeSet<String> {
        let code = line.split("//").next().unwrap_or("");
        let mut out = BTreeSet::new();
        let mut prefixes = vec!["crate::"];
        if top_level {
            prefixes.push("super::");
        }
        for prefix in prefixes {
            for (i, _) in code.match_indices(prefix) {
                let rest = &code[i + prefix.len()..];
                let group = rest
                    .strip_prefix('{')
                    .map(|g| g.split('}').next().unwrap_or(""));
                let heads: Vec<&str> = match group {
                    Some(g) => g.split(',').collect(),
                    None => vec![rest],
                };
                for h in heads {
                    let ident: String = h
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if names.contains(&ident) {
                        out.insert(ident);
                    }
                }
            }
        }
        out
    }

    /// The module graph of the crate whose sources are in `src`.
    fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
        let mut all = Vec::new();
        files(src, &mut all);
        let names: BTreeSet<String> = all.iter().filter_map(|f| module_of(src, f)).collect();
        let mut g: BTreeMap<String, BTreeSet<String>> =
            names.iter().map(|n| (n.clone(), BTreeSet::new())).collect();
        for f in &all {
            let Some(m) = module_of(src, f) else {
                continue;
            };
            let top_level = f.parent() == Some(src);
            let text = std::fs::read_to_string(f).unwrap();
            for line in text.lines() {
                for to in named(line, &names, top_level) {
                    if to != m {
                        g.get_mut(&m).unwrap().insert(to);
                    }
                }
            }
        }
        g
    }

    /// The strongly connected sets of more than one module (Tarjan's algorithm).
    fn knots(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<BTreeSet<String>> {
        struct St<'a> {
            g: &'a BTreeMap<String, BTreeSet<String>>,
            index: BTreeMap<&'a str, usize>,
            low: BTreeMap<&'a str, usize>,
            stack: Vec<&'a str>,
            on: BTreeSet<&'a str>,
            out: Vec<BTreeSet<String>>,
        }
        fn visit<'a>(s: &mut St<'a>, v: &'a str) {
            let i = s.index.len();
            s.index.insert(v, i);
            s.low.insert(v, i);
            s.stack.push(v);
            s.on.insert(v);
            for w in &s.g[v] {
                let w = w.as_str();
                if !s.index.contains_key(w) {
                    visit(s, w);
                    let lw = s.low[w];
                    let lv = s.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if s.on.contains(w) {
                    let iw = s.index[w];
                    let lv = s.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
            if s.low[v] == s.index[v] {
                let mut set = BTreeSet::new();
                while let Some(w) = s.stack.pop() {
                    s.on.remove(w);
                    set.insert(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if set.len() > 1 {
                    s.out.push(set);
                }
            }
        }
        let mut s = St {
            g,
            index: BTreeMap::new(),
            low: BTreeMap::new(),
            stack: Vec::new(),
            on: BTreeSet::new(),
            out: Vec::new(),
        };
        for v in g.keys() {
            if !s.index.contains_key(v.as_str()) {
                visit(&mut s, v);
            }
        }
        s.out
    }

    #[test]
    fn no_new_module_cycles() {
        let root = crate::project_root();
        let mut crates: Vec<(String, PathBuf)> = std::fs::read_dir(root.join("crates"))
            .unwrap()
            .flatten()
            .map(|e| {
                (
                    e.file_name().to_string_lossy().into_owned(),
                    e.path().join("src"),
                )
            })
            .collect();
        crates.push(("xtask".into(), root.join("xtask/src")));
        crates.sort();
        let mut problems = Vec::new();
        let mut found: Vec<(String, BTreeSet<String>)> = Vec::new();
        for (name, src) in &crates {
            for k in knots(&graph(src)) {
                found.push((name.clone(), k));
            }
        }
        for (name, k) in &found {
            let covered = KNOWN
                .iter()
                .any(|(c, known)| c == name && k.iter().all(|m| known.contains(&m.as_str())));
            if !covered {
                problems.push(format!("new module cycle in {name}: {k:?}"));
            }
        }
        for (c, known) in KNOWN {
            let still = found.iter().any(|(n, k)| {
                n == c && k.iter().filter(|m| known.contains(&m.as_str())).count() > 1
            });
            if !still {
                problems.push(format!(
                    "{c}: the knot {known:?} is gone: remove it from KNOWN"
                ));
            }
        }
        assert!(problems.is_empty(), "{}", problems.join("\n"));
    }

    #[test]
    fn a_cycle_is_found() {
        let mut g = BTreeMap::new();
        let set = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>();
        g.insert("a".to_string(), set(&["b"]));
        g.insert("b".to_string(), set(&["c"]));
        g.insert("c".to_string(), set(&["a"]));
        g.insert("d".to_string(), set(&["a"]));
        assert_eq!(knots(&g), vec![set(&["a", "b", "c"])]);
        let names = set(&["a", "b", "c"]);
        assert_eq!(
            named("use crate::{a, b::X};", &names, false),
            set(&["a", "b"])
        );
        assert_eq!(
            named("super::c::f() // crate::a", &names, true),
            set(&["c"])
        );
        assert!(named("super::c::f()", &names, false).is_empty());
    }
}
