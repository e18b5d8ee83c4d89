//! The house rule of runtime/diagnose/: its modules import one another
//! along a graph without cycles (a shared type or helper lives in the
//! module that owns it, or in a small module of its own), so each can be
//! read, tested and changed from the modules below it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::util::root;

/// The code of each module of the folder, without its tests and comments,
/// with the prefixes by which it names the folder's modules: a file's own
/// `super::` is the folder; in a folder module (`sanity/`), `mod.rs` says
/// `super::` and its files `super::super::`.
fn sources(dir: &Path) -> BTreeMap<String, Vec<(String, Vec<&'static str>)>> {
    let code = |path: &Path| {
        let text = std::fs::read_to_string(path).unwrap();
        let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or("");
        code.lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let mut modules = BTreeMap::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        if path.extension().is_some_and(|e| e == "rs") {
            modules.insert(
                name,
                vec![(code(&path), vec!["super::", "crate::diagnose::"])],
            );
        } else if path.join("mod.rs").exists() {
            let mut files = Vec::new();
            for file in std::fs::read_dir(&path).unwrap() {
                let file = file.unwrap().path();
                let stem = file.file_stem().unwrap().to_string_lossy().into_owned();
                if file.extension().is_none_or(|e| e != "rs") || stem == "tests" {
                    continue;
                }
                let prefixes = if stem == "mod" {
                    vec!["super::", "crate::diagnose::"]
                } else {
                    vec!["super::super::", "crate::diagnose::"]
                };
                files.push((code(&file), prefixes));
            }
            modules.insert(name, files);
        }
    }
    modules
}

/// Each module of the folder and the sibling modules its code names
/// through `super::` or `crate::diagnose::`; `mod` is the folder's own
/// `mod.rs`, and an item named on the parent (`super::Kind`) counts as an
/// edge to it.
fn imports(folder: &str) -> BTreeMap<String, BTreeSet<String>> {
    let modules = sources(&root().join(folder));
    let names: BTreeSet<String> = modules.keys().cloned().collect();
    modules
        .iter()
        .map(|(module, files)| {
            let mut used = BTreeSet::new();
            for (code, prefixes) in files {
                for line in code.lines() {
                    for prefix in prefixes {
                        for (at, _) in line.match_indices(prefix) {
                            let rest = &line[at + prefix.len()..];
                            let word: String = rest
                                .trim_start_matches('{')
                                .chars()
                                .take_while(|c| c.is_alphanumeric() || *c == '_')
                                .collect();
                            if names.contains(&word) && word != *module {
                                used.insert(word);
                            } else if word.starts_with(char::is_uppercase) && module != "mod" {
                                used.insert("mod".to_string());
                            }
                        }
                    }
                    if module == "mod" {
                        used.extend(paths_from_mod(line, &names));
                    }
                }
            }
            (module.clone(), used)
        })
        .collect()
}

/// The folder's modules `mod.rs` names on `line` (`select::select`).
fn paths_from_mod(line: &str, names: &BTreeSet<String>) -> Vec<String> {
    line.split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
        .filter_map(|word| word.split_once("::"))
        .map(|(first, _)| first.to_string())
        .filter(|first| names.contains(first) && first != "mod")
        .collect()
}

/// A cycle of the graph, if any (depth-first search).
fn cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|n| n == node) {
            let mut found = path[at..].to_vec();
            found.push(node.to_string());
            return Some(found);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(found) = visit(next, graph, path, done) {
                return Some(found);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|node| visit(node, graph, &mut Vec::new(), &mut done))
}

#[test]
fn the_diagnosis_modules_import_without_cycles() {
    let graph = imports("runtime/diagnose");
    assert!(graph.len() > 10, "{graph:?}");
    assert!(graph["select"].contains("admit"), "{graph:?}");
    assert!(graph["sanity"].contains("stacked"), "{graph:?}");
    if let Some(found) = cycle(&graph) {
        panic!(
            "runtime/diagnose/ imports in a circle: {} (move what they share into the module \
             that owns it, or a small module of its own)",
            found.join(" -> ")
        );
    }
}

#[test]
fn a_circle_is_found() {
    let graph: BTreeMap<String, BTreeSet<String>> = [("a", "b"), ("b", "c"), ("c", "a")]
        .into_iter()
        .map(|(from, to)| (from.to_string(), BTreeSet::from([to.to_string()])))
        .collect();
    assert_eq!(cycle(&graph).unwrap(), ["a", "b", "c", "a"]);
}
