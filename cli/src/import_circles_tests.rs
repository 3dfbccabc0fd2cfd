//! ARCHITECTURE.md's rule that no crate's files import each other in a
//! circle, checked on every crate of the workspace.
//!
//! The definition is `../shared/tools/cycles.py`'s, reimplemented: a file
//! uses another when it names a `crate::`, `super::` or `self::` path, or a
//! path through a child it declares with `mod child;`, that resolves to the
//! other's module (the longest prefix of the path that is a module of the
//! crate). Circles are counted between sibling modules, each with its
//! descendants: `a::x` using `b` and `b::y` using `a` is a circle of `a` and
//! `b`; a module and its own children are not. Test code is left out as the tool leaves it out:
//! files under a `tests` or `benches` folder, files named `*tests`,
//! `tests_*` or `testutil`, and `#[cfg(test)] mod name { ... }` blocks.
//! Comments, string and character literals are removed first by the
//! tool's own small lexer, so both find the same circles.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module: its path from the crate root (`[]` for `lib.rs`/`main.rs`).
type Module = Vec<String>;

fn is_word(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a source folder") {
        let path = entry.expect("an entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The crate's non-test modules and their files.
fn modules(src: &Path) -> BTreeMap<Module, PathBuf> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut mods = BTreeMap::new();
    for path in files {
        let rel = path.strip_prefix(src).expect("under the source folder").with_extension("");
        let mut m: Module = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
        if m.last().is_some_and(|l| ["mod", "lib", "main"].contains(&l.as_str())) {
            m.pop();
        }
        let test_folder = m.iter().any(|c| c == "tests" || c == "benches");
        let test_file = m.last().is_some_and(|l| l.ends_with("tests") || l.starts_with("tests_") || l == "testutil");
        if !test_folder && !test_file {
            mods.insert(m, path);
        }
    }
    mods
}

/// `text` without its `#[cfg(test)] (pub) mod name { ... }` blocks (braces
/// counted as they come, as the tool counts them).
fn strip_test_modules(text: &[char]) -> Vec<char> {
    const ATTR: &str = "#[cfg(test)]";
    let attr: Vec<char> = ATTR.chars().collect();
    let skip_ws = |mut j: usize| {
        while j < text.len() && text[j].is_whitespace() {
            j += 1;
        }
        j
    };
    let keyword = |j: usize, word: &str| -> Option<usize> {
        let w: Vec<char> = word.chars().collect();
        let end = j + w.len();
        (text.get(j..end) == Some(&w[..]) && text.get(end).is_some_and(|c| c.is_whitespace())).then_some(end)
    };
    // Where a block starts at `at`, the index of its opening brace's successor.
    let block_start = |at: usize| -> Option<usize> {
        if text.get(at..at + attr.len()) != Some(&attr[..]) {
            return None;
        }
        let mut j = skip_ws(at + attr.len());
        if let Some(end) = keyword(j, "pub") {
            j = skip_ws(end);
        }
        j = skip_ws(keyword(j, "mod")?);
        let name = j;
        while j < text.len() && is_word(text[j]) {
            j += 1;
        }
        if j == name {
            return None;
        }
        j = skip_ws(j);
        (text.get(j) == Some(&'{')).then_some(j + 1)
    };
    let mut out = Vec::with_capacity(text.len());
    let mut i = 0;
    let mut at = 0;
    while at < text.len() {
        let Some(mut j) = block_start(at) else {
            at += 1;
            continue;
        };
        out.extend_from_slice(&text[i..at]);
        let mut depth = 1;
        while j < text.len() && depth > 0 {
            match text[j] {
                '{' => depth += 1,
                '}' => depth -= 1,
                _ => {}
            }
            j += 1;
        }
        i = j;
        at = j;
    }
    out.extend_from_slice(&text[i.min(text.len())..]);
    out
}

/// `text` without its comments, strings and character literals: the
/// tool's small lexer (`code_only`). A line comment runs to its newline; a
/// block comment nests; a raw string (`r"..."`, `br#"..."#`) closes at its
/// quote and hashes; a string's backslash escapes the next character,
/// whatever it is; a character literal is a quote, one character or an
/// escape, and a quote (else the quote is a lifetime's, and stays). Each
/// string becomes `""`, each character literal `' '`.
fn code_only(text: &[char]) -> Vec<char> {
    let n = text.len();
    let at = |i: usize, s: &str| s.chars().enumerate().all(|(k, c)| text.get(i + k) == Some(&c));
    let mut out = Vec::with_capacity(n);
    let mut i = 0;
    while i < n {
        let c = text[i];
        if at(i, "//") {
            i = (i..n).find(|&k| text[k] == '\n').unwrap_or(n);
        } else if at(i, "/*") {
            let mut depth = 1;
            i += 2;
            while i < n && depth > 0 {
                if at(i, "/*") {
                    depth += 1;
                    i += 2;
                } else if at(i, "*/") {
                    depth -= 1;
                    i += 2;
                } else {
                    i += 1;
                }
            }
        } else if let Some(body) = raw_string_start(text, i) {
            let hashes = body - i - if text[i] == 'b' { 3 } else { 2 };
            let close = (body..n).find(|&k| text[k] == '"' && (1..=hashes).all(|h| text.get(k + h) == Some(&'#')));
            i = close.map_or(n, |k| k + 1 + hashes);
            out.extend(['"', '"']);
        } else if c == '"' {
            i += 1;
            while i < n && text[i] != '"' {
                i += if text[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.extend(['"', '"']);
        } else if let Some(end) = char_literal_end(text, i) {
            i = end;
            out.extend(['\'', ' ', '\'']);
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// Where a raw string starting at `i` (`r`, `br`, then hashes and a quote,
/// not inside a word) has its body: the index after its opening quote.
fn raw_string_start(text: &[char], i: usize) -> Option<usize> {
    if i > 0 && is_word(text[i - 1]) {
        return None;
    }
    let mut j = i;
    if text.get(j) == Some(&'b') {
        j += 1;
    }
    if text.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    while text.get(j) == Some(&'#') {
        j += 1;
    }
    (text.get(j) == Some(&'"')).then_some(j + 1)
}

/// The end of a character literal at `i` (`'x'`, or an escape `'\\...'` up
/// to the next quote), or `None` (a lifetime's quote).
fn char_literal_end(text: &[char], i: usize) -> Option<usize> {
    if text.get(i) != Some(&'\'') {
        return None;
    }
    match text.get(i + 1)? {
        '\\' => {
            text.get(i + 2).filter(|c| **c != '\n')?;
            (i + 3..text.len()).find(|&k| text[k] == '\'').map(|k| k + 1)
        }
        '\'' | '\n' => None,
        _ => (text.get(i + 2) == Some(&'\'')).then_some(i + 3),
    }
}

/// A path `word(::word)*` at `i`: its end, or `None` when no word starts there.
fn word_path(text: &[char], i: usize) -> Option<usize> {
    let word_end = |mut j: usize| {
        while j < text.len() && is_word(text[j]) {
            j += 1;
        }
        j
    };
    let mut end = word_end(i);
    if end == i {
        return None;
    }
    while text.get(end..end + 2) == Some(&[':', ':'][..]) && text.get(end + 2).is_some_and(|c| is_word(*c)) {
        end = word_end(end + 2);
    }
    Some(end)
}

/// What follows `prefix::` at `rest`: a path's end and its one head, or a
/// braced list's end and every path inside it up to its first `}`.
fn path_rest(text: &[char], rest: usize) -> Option<(usize, Vec<String>)> {
    if let Some(end) = word_path(text, rest) {
        return Some((end, vec![text[rest..end].iter().collect()]));
    }
    if text.get(rest) != Some(&'{') {
        return None;
    }
    let end = (rest..text.len()).find(|&k| text[k] == '}')? + 1;
    let mut heads = Vec::new();
    let mut k = rest;
    while k < end {
        match word_path(&text[..end], k) {
            Some(e) => {
                heads.push(text[k..e].iter().collect());
                k = e;
            }
            None => k += 1,
        }
    }
    Some((end, heads))
}

/// The `crate::`, `super::` and `self::` paths of `text`: `(kind, heads)`,
/// a braced list giving every path inside it up to its first `}`.
fn named_paths(text: &[char]) -> Vec<(String, Vec<String>)> {
    let mut found = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let boundary = i == 0 || !is_word(text[i - 1]);
        let kind = ["crate", "super", "self"].into_iter().find(|k| {
            let k: Vec<char> = k.chars().collect();
            text.get(i..i + k.len()) == Some(&k[..]) && text.get(i + k.len()..i + k.len() + 2) == Some(&[':', ':'][..])
        });
        let (true, Some(kind)) = (boundary, kind) else {
            i += 1;
            continue;
        };
        let Some((end, heads)) = path_rest(text, i + kind.len() + 2) else {
            i += 1;
            continue;
        };
        found.push((kind.to_string(), heads));
        i = end;
    }
    found
}

/// The children `text` declares with `mod child;` (a file of their own).
fn declared_children(text: &[char]) -> BTreeSet<String> {
    let mut kids = BTreeSet::new();
    let mut i = 0;
    while i + 3 < text.len() {
        let boundary = i == 0 || !is_word(text[i - 1]);
        if !(boundary && text[i..i + 3] == ['m', 'o', 'd'] && text[i + 3].is_whitespace()) {
            i += 1;
            continue;
        }
        let mut j = i + 3;
        while j < text.len() && text[j].is_whitespace() {
            j += 1;
        }
        let name = j;
        while j < text.len() && is_word(text[j]) {
            j += 1;
        }
        let word: String = text[name..j].iter().collect();
        while j < text.len() && text[j].is_whitespace() {
            j += 1;
        }
        if j > name && text.get(j) == Some(&';') {
            kids.insert(word);
        }
        i = j.max(i + 1);
    }
    kids
}

/// The paths through a declared child (`use child::x`, 2018 paths relative
/// to this module): `(child, heads)` for a word not after a word or a `:`.
fn child_paths(text: &[char], kids: &BTreeSet<String>) -> Vec<(String, Vec<String>)> {
    let mut found = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let starts = is_word(text[i]) && (i == 0 || !(is_word(text[i - 1]) || text[i - 1] == ':'));
        if !starts {
            i += 1;
            continue;
        }
        let mut j = i;
        while j < text.len() && is_word(text[j]) {
            j += 1;
        }
        let word: String = text[i..j].iter().collect();
        let colons = text.get(j..j + 2) == Some(&[':', ':'][..]);
        match (colons && kids.contains(&word)).then(|| path_rest(text, j + 2)).flatten() {
            Some((end, heads)) => {
                found.push((word, heads));
                i = end;
            }
            None => i = j,
        }
    }
    found
}

/// The longest prefix of `path` that is a module.
fn resolve(mut path: Module, mods: &BTreeMap<Module, PathBuf>) -> Option<Module> {
    while !path.is_empty() {
        if mods.contains_key(&path) {
            return Some(path);
        }
        path.pop();
    }
    None
}

/// Which modules each module uses: its `crate::`, `super::` and `self::`
/// paths, and its paths through a child it declares.
fn edges(mods: &BTreeMap<Module, PathBuf>) -> BTreeMap<Module, BTreeSet<Module>> {
    let mut g = BTreeMap::new();
    for (m, path) in mods {
        let text: Vec<char> = std::fs::read_to_string(path).expect("readable").chars().collect();
        let code = code_only(&strip_test_modules(&text));
        let mut used = BTreeSet::new();
        let mut add = |base: &Module, head: &str| {
            let mut full = base.clone();
            full.extend(head.split("::").map(String::from));
            if let Some(t) = resolve(full, mods).filter(|t| t != m) {
                used.insert(t);
            }
        };
        for (kind, heads) in named_paths(&code) {
            let base: Module = match kind.as_str() {
                "crate" => Vec::new(),
                "super" => m[..m.len().saturating_sub(1)].to_vec(),
                _ => m.clone(),
            };
            heads.iter().for_each(|h| add(&base, h));
        }
        for (child, heads) in child_paths(&code, &declared_children(&code)) {
            let mut base = m.clone();
            base.push(child);
            heads.iter().for_each(|h| add(&base, h));
        }
        g.insert(m.clone(), used);
    }
    g
}

/// The graph between sibling modules: an edge `a -> b` is lifted to the two
/// children of their common parent that hold them (a module with its
/// descendants is one node there); an edge between a module and its own
/// descendant (a facade re-exporting a child, a child using its parent's
/// types) is no edge.
fn lifted(g: &BTreeMap<Module, BTreeSet<Module>>) -> BTreeMap<Module, BTreeSet<Module>> {
    let mut h: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (a, bs) in g {
        for b in bs {
            let k = a.iter().zip(b).take_while(|(x, y)| x == y).count();
            if k == a.len() || k == b.len() {
                continue;
            }
            h.entry(a[..=k].to_vec()).or_default().insert(b[..=k].to_vec());
            h.entry(b[..=k].to_vec()).or_default();
        }
    }
    h
}

/// The strongly connected components of more than one module (Tarjan).
fn circles(g: &BTreeMap<Module, BTreeSet<Module>>) -> Vec<Vec<Module>> {
    struct Tarjan<'a> {
        g: &'a BTreeMap<Module, BTreeSet<Module>>,
        index: BTreeMap<&'a Module, usize>,
        low: BTreeMap<&'a Module, usize>,
        stack: Vec<&'a Module>,
        on_stack: BTreeSet<&'a Module>,
        out: Vec<Vec<Module>>,
    }
    impl<'a> Tarjan<'a> {
        fn visit(&mut self, v: &'a Module) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            self.on_stack.insert(v);
            for w in &self.g[v] {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let lw = self.low[w];
                    let lv = self.low.get_mut(v).expect("visited");
                    *lv = (*lv).min(lw);
                } else if self.on_stack.contains(w) {
                    let iw = self.index[w];
                    let lv = self.low.get_mut(v).expect("visited");
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut comp = Vec::new();
                loop {
                    let w = self.stack.pop().expect("on the stack");
                    self.on_stack.remove(w);
                    comp.push(w.clone());
                    if w == v {
                        break;
                    }
                }
                if comp.len() > 1 {
                    self.out.push(comp);
                }
            }
        }
    }
    let mut t = Tarjan {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !t.index.contains_key(v) {
            t.visit(v);
        }
    }
    t.out
}

/// Every circle between sibling modules of the crate whose sources are
/// `src`, each as the paths from the workspace root of its modules' files
/// and their descendants', sorted.
fn circles_of(root: &Path, src: &Path) -> Vec<Vec<String>> {
    let mods = modules(src);
    let mut out: Vec<Vec<String>> = circles(&lifted(&edges(&mods)))
        .into_iter()
        .map(|c| {
            let mut files: Vec<String> = mods
                .iter()
                .filter(|(m, _)| c.iter().any(|node| m.starts_with(node)))
                .map(|(_, p)| p.strip_prefix(root).expect("in the workspace").to_string_lossy().into_owned())
                .collect();
            files.sort();
            files
        })
        .collect();
    out.sort();
    out
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the workspace root").to_path_buf()
}

#[test]
fn no_crate_has_an_import_circle() {
    let root = root();
    let mut crates: Vec<PathBuf> = std::fs::read_dir(&root)
        .expect("the workspace root")
        .map(|e| e.expect("an entry").path())
        .filter(|p| p.join("Cargo.toml").is_file() && p.join("src").is_dir())
        .collect();
    crates.push(root.clone());
    crates.sort();
    let mut found = Vec::new();
    for c in &crates {
        found.extend(circles_of(&root, &c.join("src")));
    }
    assert!(crates.len() >= 5, "the workspace's crates were found: {crates:?}");
    assert!(found.is_empty(), "files that import each other in a circle (non-test code): {found:?}");
}

/// The rules above on small texts: what counts as naming a module, and
/// what test code, comments and strings hide.
#[test]
fn the_rules_read_paths_as_the_tool_does() {
    let chars = |s: &str| s.chars().collect::<Vec<char>>();
    let text = chars(
        "use crate::a::b;\nuse super::{c, d::e, self};\nuse super::super::f;\n// crate::hidden\n\
         let s = \"crate::in_a_string\";\n/* crate::in_a_block */\n#[cfg(test)]\nmod tests { use crate::t; }\n\
         x = mycrate::no;\n",
    );
    let code = code_only(&strip_test_modules(&text));
    let paths = named_paths(&code);
    let want = [("crate", vec!["a::b"]), ("super", vec!["c", "d::e", "self"]), ("super", vec!["super::f"])];
    assert_eq!(paths.len(), want.len(), "{paths:?}");
    for ((kind, heads), (k, h)) in paths.iter().zip(want) {
        assert_eq!((kind.as_str(), heads.iter().map(String::as_str).collect::<Vec<_>>()), (k, h));
    }
    // The lexer: an escaped quote does not end a string; raw strings close
    // at their hashes; block comments nest; a quote in a character literal
    // starts no string; a lifetime is no literal.
    let lexed = |t: &str| code_only(&chars(t)).iter().collect::<String>();
    assert_eq!(lexed("\"a\\\"b\" crate::x"), "\"\" crate::x");
    assert_eq!(lexed("\"a\\\nb\" c"), "\"\" c");
    assert_eq!(lexed("r#\"crate::\"no\"# br\"x\" y"), "\"\" \"\" y");
    assert_eq!(lexed("/* a /* b */ crate::no */ z"), " z");
    assert_eq!(lexed("'\"' crate::y '\\'' '\\u{41}' q"), "' ' crate::y ' ' ' ' q");
    assert_eq!(lexed("fn f<'a>(x: &'a str) -> char { 'b' }"), "fn f<'a>(x: &'a str) -> char { ' ' }");
    assert_eq!(lexed("bar\"s\" // crate::no\nk"), "bar\"\" \nk");
    // Two files that name each other are a circle; a third that names one is not in it.
    let m = |s: &str| -> Module { s.split('/').filter(|x| !x.is_empty()).map(String::from).collect() };
    let g: BTreeMap<Module, BTreeSet<Module>> =
        [(m("a"), [m("b")].into()), (m("b"), [m("a")].into()), (m("c"), [m("a")].into())].into();
    let found = circles(&g);
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].iter().collect::<BTreeSet<_>>(), [m("a"), m("b")].iter().collect());
    // Between siblings: a child of `a` naming `b` and a child of `b` naming
    // `a` is a circle of `a` and `b`; a parent and its child are none.
    let g: BTreeMap<Module, BTreeSet<Module>> = [
        (m("a/x"), [m("b")].into()),
        (m("b/y"), [m("a/z")].into()),
        (m("c"), [m("c/k")].into()),
        (m("c/k"), [m("c")].into()),
    ]
    .into();
    let found = circles(&lifted(&g));
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].iter().collect::<BTreeSet<_>>(), [m("a"), m("b")].iter().collect());
    // Paths through a declared child, and only a declared one.
    let code =
        code_only(&chars("mod kid;\npub mod open { }\nuse kid::{x, y::z};\nuse other::w;\nlet v = a::kid::no;\n"));
    let kids = declared_children(&code);
    assert_eq!(kids, ["kid".to_string()].into());
    let through = child_paths(&code, &kids);
    assert_eq!(through, [("kid".to_string(), vec!["x".to_string(), "y::z".to_string()])]);
}

/// A small crate on disk with the circle the tool found in `processing`
/// (a child of one module naming a sibling that names the module back) is
/// found, with its modules' files; the same crate without the back edge is not.
#[test]
fn a_circle_through_a_child_is_found_on_disk() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let src = dir.path().join("src");
    std::fs::create_dir_all(src.join("recipe")).expect("folders");
    let write = |p: &str, t: &str| std::fs::write(src.join(p), t).expect("written");
    write("lib.rs", "pub mod correction;\npub mod recipe;\n");
    write("correction.rs", "mod left;\npub use left::Left;\n");
    std::fs::create_dir_all(src.join("correction")).expect("folders");
    write("correction/left.rs", "use crate::recipe::Decisions;\npub struct Left;\n");
    write("recipe.rs", "mod build;\npub struct Decisions;\n");
    write("recipe/build.rs", "use crate::correction::Left;\n");
    let found = circles_of(dir.path(), &src);
    assert_eq!(
        found,
        [vec!["src/correction.rs", "src/correction/left.rs", "src/recipe.rs", "src/recipe/build.rs"]]
            .map(|v| v.into_iter().map(String::from).collect::<Vec<_>>())
    );
    write("recipe/build.rs", "pub struct Build;\n");
    assert!(circles_of(dir.path(), &src).is_empty());
}

/// The graph of a crate's top-level modules as ARCHITECTURE.md draws it: a
/// header `DIR/src (N modules)`, then one line a module, `  name -> the
/// modules it uses` (`(none)` for a leaf).
fn module_graph_text(root: &Path, dir: &str) -> String {
    let mods = modules(&root.join(dir).join("src"));
    let mut top: BTreeMap<String, BTreeSet<String>> =
        mods.keys().filter_map(|m| m.first()).map(|t| (t.clone(), BTreeSet::new())).collect();
    for (a, bs) in edges(&mods) {
        for b in bs {
            if let (Some(x), Some(y)) = (a.first(), b.first())
                && x != y
            {
                top.entry(x.clone()).or_default().insert(y.clone());
            }
        }
    }
    let width = top.keys().map(String::len).max().unwrap_or(0);
    let mut out = format!("{dir}/src ({} modules)\n", top.len());
    for (m, uses) in &top {
        let uses =
            if uses.is_empty() { "(none)".to_string() } else { uses.iter().cloned().collect::<Vec<_>>().join(", ") };
        out.push_str(&format!("  {m:width$} -> {uses}\n"));
    }
    out
}

/// ARCHITECTURE.md shows the module graph of every crate with more than
/// five top-level modules, as the code has it now.
#[test]
fn architecture_shows_each_large_crates_module_graph() {
    let root = root();
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let mut dirs: Vec<String> = std::fs::read_dir(&root)
        .expect("the workspace root")
        .map(|e| e.expect("an entry").path())
        .filter(|p| p.join("Cargo.toml").is_file() && p.join("src").is_dir() && p != &root)
        .map(|p| p.file_name().expect("a name").to_string_lossy().into_owned())
        .collect();
    dirs.sort();
    let mut shown = 0;
    let mut missing = String::new();
    for dir in &dirs {
        let count = modules(&root.join(dir).join("src")).keys().filter(|m| m.len() == 1).count();
        if count <= 5 {
            continue;
        }
        let want = module_graph_text(&root, dir);
        if !doc.contains(&want) {
            missing.push_str(&want);
            missing.push('\n');
        }
        shown += 1;
    }
    assert!(missing.is_empty(), "ARCHITECTURE.md does not show these module graphs as the code has them:\n\n{missing}");
    assert!(shown >= 8, "only {shown} crates have more than five modules: the crates moved?");
}
