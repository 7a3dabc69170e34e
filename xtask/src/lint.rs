//! `cargo xtask lint`: the project's own rules that rustc, clippy and rustfmt do not check.
//!
//! 1. Wording: code, comments and documentation speak of the product. A ticket reference (the
//!    word for a tracker ticket followed by a number, with or without `#`) or a work-log word
//!    (the word for a working sitting) in a `.rs`, `.md` or `.toml`
//!    file of the repository is an error naming the file, line and column.
//! 2. The library crates ([`LIBRARY_CRATES`]) do not depend on `clap`: their option enums
//!    implement `FromStr` and `Display` (with `strum`) and the binaries turn them into clap
//!    values, so no clap type is part of a library's public API.
//! 3. The crates with a library and a command line ([`CLI_CRATES`]) keep their clap argument
//!    structs at the command line: a `pub fn` of the library (every `src/` file but `main.rs`
//!    and the modules `main.rs` declares) may not take a struct deriving clap's `Args` or
//!    `Parser` (by value, by reference or inside another type): it takes a typed options
//!    struct, which the arguments convert into. The one exception is a free function `run`
//!    taking the struct by value, a sub-command's entry point that the binary calls.
//! 4. A function in a `src/` file has a body of at most [`MAX_FN_LINES`] lines (measured with
//!    `syn` from the opening to the closing brace). The functions that were longer when the
//!    rule came in are listed with their length in [`ALLOWLIST`]: such a function may shrink
//!    but not grow, and when it shrinks its entry must follow
//!    (`cargo xtask lint --update-allowlist` lowers and removes entries, it never adds or
//!    raises one).
//! 5. The crates whose test harnesses cargo does not build ([`NO_HARNESS`], `test = false` in
//!    their manifest: a harness would compile the whole crate once more in the release test
//!    build for no test of its own) have no `#[cfg(test)]` in the files of those targets: such
//!    a test would never run. Their tests are in the crate's `tests/it`.

use anyhow::{bail, Context, Result};
use regex::Regex;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use syn::visit::Visit;

/// The longest function body allowed, in lines (opening to closing brace, inclusive).
pub const MAX_FN_LINES: usize = 120;

/// The library crates that must not depend on `clap`.
pub const LIBRARY_CRATES: [&str; 7] = [
    "nav-core",
    "nav-io",
    "nav-engine",
    "noise-id",
    "nav-sim",
    "nav-study",
    "nav-diagnose",
];

/// The crates with both a library and a binary whose library functions may not take the
/// binary's clap argument structs (rule 3).
pub const CLI_CRATES: [&str; 2] = ["host-sim", "hw-bridge"];

/// Which of a crate's targets have no test harness (`test = false`), for rule 5.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoHarness {
    /// The library and the binaries: every `src/` file.
    All,
    /// The library only: every `src/` file but `main.rs`, `src/bin/` and the modules
    /// `main.rs` declares.
    Library,
}

/// The crates whose test harnesses are off (`test = false` in their manifest), for rule 5.
pub const NO_HARNESS: [(&str, NoHarness); 4] = [
    ("host-sim", NoHarness::All),
    ("hw-bridge", NoHarness::Library),
    ("nav-app", NoHarness::All),
    ("tests", NoHarness::All),
];

/// The allowlist of functions longer than [`MAX_FN_LINES`], relative to the workspace root:
/// one `LINES PATH NAME` a line, `#` comments.
pub const ALLOWLIST: &str = "xtask/long-functions.txt";

/// Directories never scanned.
const SKIP_DIRS: [&str; 5] = ["target", "node_modules", "corpus", "artifacts", "coverage"];

/// One violation, located in a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    /// File, relative to the workspace root.
    pub path: PathBuf,
    /// 1-based line (0 when the finding is about the whole file).
    pub line: usize,
    /// 1-based column (0 when not applicable).
    pub col: usize,
    /// What is wrong and what to do.
    pub message: String,
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, self.col) {
            (0, _) => write!(f, "{}: {}", self.path.display(), self.message),
            (l, 0) => write!(f, "{}:{l}: {}", self.path.display(), self.message),
            (l, c) => write!(f, "{}:{l}:{c}: {}", self.path.display(), self.message),
        }
    }
}

/// The wording patterns (case-insensitive), each with the reason shown to the user. Written so
/// that this file's own text does not match them.
fn wording_patterns() -> Vec<(Regex, &'static str)> {
    let p = |re: &str| Regex::new(&format!("(?i){re}")).expect("static pattern");
    vec![
        (
            p(r"\bissues?\s*#?[0-9]+"),
            "a ticket reference: say what the code does instead",
        ),
        (
            p(r"\bissue'(?:s)\b"),
            "a ticket reference: say what the code does instead",
        ),
        (
            p(r"\bsess(?:ion)s?\b"),
            "a work-log word: state the fact, not when it was found",
        ),
    ]
}

/// Wording findings in `text`: (line, column, matched text, reason), 1-based.
pub fn wording(text: &str) -> Vec<(usize, usize, String, &'static str)> {
    let pats = wording_patterns();
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        for (re, why) in &pats {
            for m in re.find_iter(line) {
                let col = line[..m.start()].chars().count() + 1;
                out.push((i + 1, col, m.as_str().to_string(), *why));
            }
        }
    }
    out.sort();
    out
}

/// The dependency tables of a manifest that name `clap` (`[dependencies]`,
/// `[target.*.dependencies]`, also as `package = "clap"` under another name).
pub fn clap_dependencies(manifest: &str) -> Result<Vec<String>> {
    let v: toml::Value = toml::from_str(manifest).context("not a valid Cargo.toml")?;
    let mut tables: Vec<(String, &toml::Value)> = Vec::new();
    if let Some(d) = v.get("dependencies") {
        tables.push(("[dependencies]".into(), d));
    }
    if let Some(t) = v.get("target").and_then(|t| t.as_table()) {
        for (cfg, tv) in t {
            if let Some(d) = tv.get("dependencies") {
                tables.push((format!("[target.'{cfg}'.dependencies]"), d));
            }
        }
    }
    let mut out = Vec::new();
    for (name, deps) in tables {
        for (key, spec) in deps.as_table().into_iter().flatten() {
            let package = spec.get("package").and_then(|p| p.as_str()).unwrap_or(key);
            if package == "clap" {
                out.push(format!("{name} {key}"));
            }
        }
    }
    Ok(out)
}

/// A function found in a source file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FnLen {
    /// Qualified name within the file: modules, `Type` or `<Type as Trait>`, enclosing
    /// functions, then the name; `#2`, `#3` appended to repeats.
    pub name: String,
    /// Line of the opening brace of the body.
    pub line: usize,
    /// Lines from the opening to the closing brace of the body, inclusive.
    pub lines: usize,
}

struct FnVisitor {
    scope: Vec<String>,
    found: Vec<FnLen>,
}

impl FnVisitor {
    fn record(&mut self, ident: &syn::Ident, block: &syn::Block) {
        let open = block.brace_token.span.open().start().line;
        let close = block.brace_token.span.close().end().line;
        let mut name = self.scope.clone();
        name.push(ident.to_string());
        self.found.push(FnLen {
            name: name.join("::"),
            line: open,
            lines: close.saturating_sub(open) + 1,
        });
    }
}

fn last_ident(path: &syn::Path) -> String {
    path.segments
        .last()
        .map(|s| s.ident.to_string())
        .unwrap_or_else(|| "_".into())
}

fn type_name(ty: &syn::Type) -> String {
    match ty {
        syn::Type::Path(p) => last_ident(&p.path),
        syn::Type::Reference(r) => type_name(&r.elem),
        _ => "_".into(),
    }
}

impl<'ast> Visit<'ast> for FnVisitor {
    fn visit_item_fn(&mut self, f: &'ast syn::ItemFn) {
        self.record(&f.sig.ident, &f.block);
        self.scope.push(f.sig.ident.to_string());
        syn::visit::visit_item_fn(self, f);
        self.scope.pop();
    }
    fn visit_impl_item_fn(&mut self, f: &'ast syn::ImplItemFn) {
        self.record(&f.sig.ident, &f.block);
        self.scope.push(f.sig.ident.to_string());
        syn::visit::visit_impl_item_fn(self, f);
        self.scope.pop();
    }
    fn visit_trait_item_fn(&mut self, f: &'ast syn::TraitItemFn) {
        if let Some(b) = &f.default {
            self.record(&f.sig.ident, b);
        }
        self.scope.push(f.sig.ident.to_string());
        syn::visit::visit_trait_item_fn(self, f);
        self.scope.pop();
    }
    fn visit_item_impl(&mut self, i: &'ast syn::ItemImpl) {
        let ty = type_name(&i.self_ty);
        let scope = match &i.trait_ {
            Some((_, path, _)) => format!("<{ty} as {}>", last_ident(path)),
            None => ty,
        };
        self.scope.push(scope);
        syn::visit::visit_item_impl(self, i);
        self.scope.pop();
    }
    fn visit_item_trait(&mut self, t: &'ast syn::ItemTrait) {
        self.scope.push(t.ident.to_string());
        syn::visit::visit_item_trait(self, t);
        self.scope.pop();
    }
    fn visit_item_mod(&mut self, m: &'ast syn::ItemMod) {
        self.scope.push(m.ident.to_string());
        syn::visit::visit_item_mod(self, m);
        self.scope.pop();
    }
}

/// Whether an item's attributes derive clap's `Args` or `Parser` (any path ending so).
fn derives_clap_args(attrs: &[syn::Attribute]) -> bool {
    attrs
        .iter()
        .filter(|a| a.path().is_ident("derive"))
        .any(|a| {
            let mut found = false;
            let _ = a.parse_nested_meta(|m| {
                let last = last_ident(&m.path);
                found |= last == "Args" || last == "Parser";
                Ok(())
            });
            found
        })
}

/// The names of the structs deriving clap's `Args` or `Parser` in a source file.
pub fn clap_arg_structs(src: &str) -> Result<Vec<String>, syn::Error> {
    struct V(Vec<String>);
    impl<'ast> Visit<'ast> for V {
        fn visit_item_struct(&mut self, s: &'ast syn::ItemStruct) {
            if derives_clap_args(&s.attrs) {
                self.0.push(s.ident.to_string());
            }
        }
    }
    let mut v = V(Vec::new());
    v.visit_file(&syn::parse_file(src)?);
    Ok(v.0)
}

/// The identifiers of every path in a type (`&Option<cli::RunArgs>`: `Option`, `cli`,
/// `RunArgs`).
fn type_idents(ty: &syn::Type) -> Vec<String> {
    struct V(Vec<String>);
    impl<'ast> Visit<'ast> for V {
        fn visit_path_segment(&mut self, s: &'ast syn::PathSegment) {
            self.0.push(s.ident.to_string());
            syn::visit::visit_path_segment(self, s);
        }
    }
    let mut v = V(Vec::new());
    v.visit_type(ty);
    v.0
}

/// The `pub fn`s of a library source file that take one of the clap argument structs
/// `args` (rule 3): (line, column, message), 1-based. A free function `run` taking the struct
/// by value (a sub-command's entry point) is allowed.
pub fn args_in_library_api(
    src: &str,
    args: &[String],
) -> Result<Vec<(usize, usize, String)>, syn::Error> {
    struct V<'a> {
        args: &'a [String],
        out: Vec<(usize, usize, String)>,
    }
    impl V<'_> {
        fn check(&mut self, vis: &syn::Visibility, sig: &syn::Signature, free: bool) {
            if !matches!(vis, syn::Visibility::Public(_)) {
                return;
            }
            for input in &sig.inputs {
                let syn::FnArg::Typed(pt) = input else {
                    continue;
                };
                let Some(name) = type_idents(&pt.ty)
                    .into_iter()
                    .find(|i| self.args.contains(i))
                else {
                    continue;
                };
                let entry_point = free
                    && sig.ident == "run"
                    && matches!(&*pt.ty, syn::Type::Path(p) if last_ident(&p.path) == name);
                if entry_point {
                    continue;
                }
                let at = sig.ident.span().start();
                self.out.push((
                    at.line,
                    at.column + 1,
                    format!(
                        "pub fn {} takes the command-line struct `{name}` (clap): take a typed \
                         options struct that `{name}` converts into (only a sub-command's \
                         `pub fn run({name})` entry point takes it)",
                        sig.ident
                    ),
                ));
            }
        }
    }
    impl<'ast> Visit<'ast> for V<'_> {
        fn visit_item_fn(&mut self, f: &'ast syn::ItemFn) {
            self.check(&f.vis, &f.sig, true);
            syn::visit::visit_item_fn(self, f);
        }
        fn visit_item_impl(&mut self, i: &'ast syn::ItemImpl) {
            if i.trait_.is_none() {
                for item in &i.items {
                    if let syn::ImplItem::Fn(f) = item {
                        self.check(&f.vis, &f.sig, false);
                    }
                }
            }
            syn::visit::visit_item_impl(self, i);
        }
    }
    let mut v = V {
        args,
        out: Vec::new(),
    };
    v.visit_file(&syn::parse_file(src)?);
    Ok(v.out)
}

/// The modules `main.rs` declares (`mod cli;`): the binary's own files, not the library's.
fn binary_modules(main_rs: &str) -> Result<Vec<String>, syn::Error> {
    Ok(syn::parse_file(main_rs)?
        .items
        .iter()
        .filter_map(|i| match i {
            syn::Item::Mod(m) if m.content.is_none() => Some(m.ident.to_string()),
            _ => None,
        })
        .collect())
}

/// Rule 3 over one crate of [`CLI_CRATES`] at `root`.
fn check_cli_crate(root: &Path, krate: &str) -> Result<Vec<Finding>> {
    let lib: Vec<(String, String)> = library_files(root, krate)?
        .iter()
        .map(|p| Ok((rel(root, p), std::fs::read_to_string(p)?)))
        .collect::<Result<_>>()?;
    let mut args = Vec::new();
    for (_, text) in &lib {
        // a file that does not parse is reported by the length rule
        args.extend(clap_arg_structs(text).unwrap_or_default());
    }
    let mut findings = Vec::new();
    for (r, text) in &lib {
        for (line, col, message) in args_in_library_api(text, &args).unwrap_or_default() {
            findings.push(Finding {
                path: PathBuf::from(r),
                line,
                col,
                message,
            });
        }
    }
    Ok(findings)
}

/// The `src/` files of `krate` that belong to the library, not to a binary: every file but
/// `main.rs`, `src/bin/` and the modules `main.rs` declares.
fn library_files(root: &Path, krate: &str) -> Result<Vec<PathBuf>> {
    let src = root.join(krate).join("src");
    let main_rs = src.join("main.rs");
    let bin_mods = match std::fs::read_to_string(&main_rs) {
        Ok(t) => binary_modules(&t).with_context(|| format!("{krate}/src/main.rs"))?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e).with_context(|| format!("reading {krate}/src/main.rs")),
    };
    let mut all = Vec::new();
    files(&src, &[".rs"], &mut all)?;
    all.retain(|p| {
        let r = p.strip_prefix(&src).unwrap_or(p);
        let first = r
            .components()
            .next()
            .map(|c| {
                c.as_os_str()
                    .to_string_lossy()
                    .trim_end_matches(".rs")
                    .to_string()
            })
            .unwrap_or_default();
        first != "main" && first != "bin" && !bin_mods.contains(&first)
    });
    Ok(all)
}

/// Rule 5 over one crate of [`NO_HARNESS`] at `root`: each `#[cfg(test)]` in a file of a
/// target without a harness.
fn check_no_harness(root: &Path, krate: &str, which: NoHarness) -> Result<Vec<Finding>> {
    let paths = match which {
        NoHarness::All => {
            let mut all = Vec::new();
            files(&root.join(krate).join("src"), &[".rs"], &mut all)?;
            all
        }
        NoHarness::Library => library_files(root, krate)?,
    };
    let mut findings = Vec::new();
    for p in paths {
        let r = rel(root, &p);
        let text = std::fs::read_to_string(&p).with_context(|| format!("reading {r}"))?;
        findings.extend(cfg_test_lines(&text).into_iter().map(|line| Finding {
            path: PathBuf::from(&r),
            line,
            col: 0,
            message: format!(
                "`#[cfg(test)]` in a target of {krate} built without a test harness \
                 (`test = false`): it would never run; put the test in {krate}/tests/it"
            ),
        }));
    }
    Ok(findings)
}

/// The 1-based lines of `src` (Rust source) that carry `#[cfg(test)]`.
pub fn cfg_test_lines(src: &str) -> Vec<usize> {
    src.lines()
        .enumerate()
        .filter(|(_, l)| l.trim_start().starts_with("#[cfg(test)]"))
        .map(|(i, _)| i + 1)
        .collect()
}

/// Every function with a body in `src` (Rust source), in order of appearance.
pub fn functions(src: &str) -> Result<Vec<FnLen>, syn::Error> {
    let file = syn::parse_file(src)?;
    let mut v = FnVisitor {
        scope: Vec::new(),
        found: Vec::new(),
    };
    v.visit_file(&file);
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    for f in &mut v.found {
        let n = seen.entry(f.name.clone()).or_insert(0);
        *n += 1;
        if *n > 1 {
            f.name = format!("{}#{n}", f.name);
        }
    }
    Ok(v.found)
}

/// The allowlist: (path, name) -> allowed lines.
pub type Allowlist = BTreeMap<(String, String), usize>;

/// Parses the allowlist text (`LINES PATH NAME` a line, `#` comments, blank lines).
pub fn parse_allowlist(text: &str) -> Result<Allowlist> {
    let mut out = Allowlist::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut it = line.split_whitespace();
        let (Some(n), Some(path), Some(name), None) = (it.next(), it.next(), it.next(), it.next())
        else {
            bail!(
                "{ALLOWLIST}:{}: expected `LINES PATH NAME`, found `{line}`",
                i + 1
            );
        };
        let n: usize = n
            .parse()
            .with_context(|| format!("{ALLOWLIST}:{}: `{n}` is not a line count", i + 1))?;
        if out
            .insert((path.to_string(), name.to_string()), n)
            .is_some()
        {
            bail!("{ALLOWLIST}:{}: {path} {name} listed twice", i + 1);
        }
    }
    Ok(out)
}

/// Renders an allowlist in its file format.
pub fn render_allowlist(a: &Allowlist) -> String {
    let mut s = String::from(
        "# Functions whose body was longer than the limit of `cargo xtask lint` (120 lines) when\n\
         # the rule came in: LINES PATH NAME. An entry may only go down: a listed function may\n\
         # not grow, and `cargo xtask lint --update-allowlist` lowers an entry when its function\n\
         # shrinks and removes it once the function is within the limit or gone.\n",
    );
    for ((path, name), n) in a {
        s.push_str(&format!("{n} {path} {name}\n"));
    }
    s
}

/// Checks measured function lengths (`(path, function)` pairs) against the allowlist. Returns
/// the findings and the allowlist as it should now read (entries lowered or removed, none
/// added or raised).
pub fn check_lengths(found: &[(String, FnLen)], allow: &Allowlist) -> (Vec<Finding>, Allowlist) {
    let mut findings = Vec::new();
    let mut updated = Allowlist::new();
    let mut present: BTreeMap<(String, String), usize> = BTreeMap::new();
    for (path, f) in found {
        let key = (path.clone(), f.name.clone());
        present.insert(key.clone(), f.lines);
        let at = |message: String| Finding {
            path: PathBuf::from(path),
            line: f.line,
            col: 0,
            message,
        };
        match allow.get(&key) {
            None if f.lines > MAX_FN_LINES => findings.push(at(format!(
                "fn {} has a {}-line body (limit {MAX_FN_LINES}): split it",
                f.name, f.lines
            ))),
            None => {}
            Some(&n) if f.lines > n => findings.push(at(format!(
                "fn {} grew to {} lines; {ALLOWLIST} allows {n} (the limit is {MAX_FN_LINES}): \
                 split it rather than let it grow",
                f.name, f.lines
            ))),
            Some(&n) => {
                if f.lines > MAX_FN_LINES {
                    updated.insert(key.clone(), f.lines);
                }
                if f.lines < n {
                    findings.push(at(format!(
                        "fn {} is now {} lines, {ALLOWLIST} still says {n}: run \
                         `cargo xtask lint --update-allowlist` to lower the entry",
                        f.name, f.lines
                    )));
                }
            }
        }
        if let Some(&n) = allow.get(&key) {
            if f.lines > n {
                updated.insert(key, n);
            }
        }
    }
    for ((path, name), n) in allow {
        if !present.contains_key(&(path.clone(), name.clone())) {
            findings.push(Finding {
                path: PathBuf::from(ALLOWLIST),
                line: 0,
                col: 0,
                message: format!(
                    "{path} {name} ({n} lines) no longer exists: run \
                     `cargo xtask lint --update-allowlist` to remove the entry"
                ),
            });
        }
    }
    (findings, updated)
}

/// Every file under `dir` whose name ends with one of `exts`, skipping hidden and build
/// directories, sorted.
fn files(dir: &Path, exts: &[&str], out: &mut Vec<PathBuf>) -> Result<()> {
    let rd = std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))?;
    for e in rd {
        let e = e?;
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if e.file_type()?.is_dir() {
            if !name.starts_with('.') && !SKIP_DIRS.contains(&name.as_str()) {
                files(&p, exts, out)?;
            }
        } else if exts.iter().any(|x| name.ends_with(x)) {
            out.push(p);
        }
    }
    out.sort();
    Ok(())
}

fn rel(root: &Path, p: &Path) -> String {
    p.strip_prefix(root)
        .unwrap_or(p)
        .to_string_lossy()
        .replace('\\', "/")
}

/// Whether a path (relative, `/`-separated) is in a `src/` directory.
fn in_src(rel: &str) -> bool {
    rel.starts_with("src/") || rel.contains("/src/")
}

/// All four checks over the repository at `root`. With `update_allowlist`, writes the
/// lowered allowlist first.
pub fn check_repo(root: &Path, update_allowlist: bool) -> Result<Vec<Finding>> {
    let mut findings = Vec::new();
    let mut all = Vec::new();
    files(root, &[".rs", ".md", ".toml"], &mut all)?;
    let mut lengths = Vec::new();
    for p in &all {
        let r = rel(root, p);
        let text = std::fs::read_to_string(p).with_context(|| format!("reading {r}"))?;
        for (line, col, m, why) in wording(&text) {
            findings.push(Finding {
                path: PathBuf::from(&r),
                line,
                col,
                message: format!("`{m}`: {why}"),
            });
        }
        if r.ends_with(".rs") && in_src(&r) {
            match functions(&text) {
                Ok(fs) => lengths.extend(fs.into_iter().map(|f| (r.clone(), f))),
                Err(e) => {
                    let s = e.span().start();
                    findings.push(Finding {
                        path: PathBuf::from(&r),
                        line: s.line,
                        col: s.column + 1,
                        message: format!("does not parse: {e}"),
                    });
                }
            }
        }
    }
    for krate in LIBRARY_CRATES {
        let manifest = format!("{krate}/Cargo.toml");
        let text = std::fs::read_to_string(root.join(&manifest))
            .with_context(|| format!("reading {manifest}"))?;
        for table in clap_dependencies(&text).with_context(|| manifest.clone())? {
            findings.push(Finding {
                path: PathBuf::from(&manifest),
                line: 0,
                col: 0,
                message: format!(
                    "{table}: clap in a library crate; implement FromStr/Display (strum) and \
                     parse in the binary (host-sim's `cli_enum::parser`)"
                ),
            });
        }
    }
    for krate in CLI_CRATES {
        findings.extend(check_cli_crate(root, krate)?);
    }
    for (krate, which) in NO_HARNESS {
        findings.extend(check_no_harness(root, krate, which)?);
    }
    let allow_path = root.join(ALLOWLIST);
    let allow = match std::fs::read_to_string(&allow_path) {
        Ok(t) => parse_allowlist(&t)?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Allowlist::new(),
        Err(e) => return Err(e).with_context(|| format!("reading {ALLOWLIST}")),
    };
    let (mut f, updated) = check_lengths(&lengths, &allow);
    if update_allowlist && updated != allow {
        std::fs::write(&allow_path, render_allowlist(&updated))
            .with_context(|| format!("writing {ALLOWLIST}"))?;
        eprintln!(
            "  {ALLOWLIST}: {} -> {} entries",
            allow.len(),
            updated.len()
        );
        f = check_lengths(&lengths, &updated).0;
    }
    findings.extend(f);
    eprintln!(
        "  lint: {} files, {} functions in src/, {} findings",
        all.len(),
        lengths.len(),
        findings.len()
    );
    Ok(findings)
}

/// `cargo xtask lint [--update-allowlist]`: prints every finding, fails when there is one.
pub fn run(update_allowlist: bool) -> Result<()> {
    let findings = check_repo(&crate::root(), update_allowlist)?;
    for f in &findings {
        eprintln!("{f}");
    }
    if !findings.is_empty() {
        bail!("{} lint finding(s)", findings.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ticket reference and a work-log word, assembled so this file does not contain them.
    fn bad_words() -> (String, String) {
        (
            format!("// fixed for {} 17 and #{}", "issue", 3),
            format!("/// measured in the last {}", concat!("sess", "ion")),
        )
    }

    #[test]
    fn wording_flags_ticket_numbers_and_work_log_words_with_their_position() {
        let (ticket, log) = bad_words();
        let text = format!("fn a() {{}}\n{ticket}\n{log}\n");
        let w = wording(&text);
        assert_eq!(w.len(), 2, "{w:?}");
        assert_eq!((w[0].0, w[0].1), (2, 14));
        assert_eq!(w[0].2, format!("{} 17", "issue"));
        assert_eq!(w[1].0, 3);
        assert!(wording(&format!("see {} #42", "Issue")).len() == 1);
    }

    #[test]
    fn wording_passes_product_text() {
        let ok = "/// The IMU gap is bridged by the next increment (2 samples, 10 ms).\n\
                  // An issuer of 3 fixes; a tissue 4; the last round of the search.\n";
        assert!(wording(ok).is_empty(), "{:?}", wording(ok));
    }

    #[test]
    fn clap_in_a_library_manifest_is_found_also_renamed_or_target_specific() {
        let bad = "[package]\nname = \"l\"\n[dependencies]\nclap = { version = \"4\", optional = true }\n";
        assert_eq!(clap_dependencies(bad).unwrap(), ["[dependencies] clap"]);
        let renamed =
            "[target.'cfg(unix)'.dependencies]\ncli = { package = \"clap\", version = \"4\" }\n";
        assert_eq!(
            clap_dependencies(renamed).unwrap(),
            ["[target.'cfg(unix)'.dependencies] cli"]
        );
        let ok = "[dependencies]\nstrum = \"0.28\"\n[dev-dependencies]\nclap = \"4\"\n";
        assert!(clap_dependencies(ok).unwrap().is_empty());
    }

    fn body(lines: usize) -> String {
        let mut s = String::from("{\n");
        for i in 0..lines.saturating_sub(2) {
            s.push_str(&format!("    let _x{i} = {i};\n"));
        }
        s.push_str("}\n");
        s
    }

    #[test]
    fn function_bodies_are_measured_and_named_by_their_scope() {
        let src = format!(
            "fn short() {{}}\nimpl Foo {{ fn long() {} }}\nimpl std::fmt::Display for Foo {{ fn fmt() {} }}\nmod m {{ fn g() {{ fn inner() {{}} }} }}\n",
            body(130),
            body(5)
        );
        let f = functions(&src).unwrap();
        let names: Vec<(&str, usize)> = f.iter().map(|f| (f.name.as_str(), f.lines)).collect();
        assert_eq!(
            names,
            [
                ("short", 1),
                ("Foo::long", 130),
                ("<Foo as Display>::fmt", 5),
                ("m::g", 1),
                ("m::g::inner", 1)
            ]
        );
    }

    fn measured(src: &str) -> Vec<(String, FnLen)> {
        functions(src)
            .unwrap()
            .into_iter()
            .map(|f| ("a/src/lib.rs".to_string(), f))
            .collect()
    }

    #[test]
    fn a_long_function_fails_unless_listed_and_a_listed_one_may_not_grow() {
        let long = measured(&format!("fn long() {}", body(130)));
        let (f, _) = check_lengths(&long, &Allowlist::new());
        assert_eq!(f.len(), 1);
        assert!(
            f[0].message.contains("130-line body (limit 120)"),
            "{}",
            f[0]
        );
        let allow = parse_allowlist("# c\n130 a/src/lib.rs long\n").unwrap();
        let (f, updated) = check_lengths(&long, &allow);
        assert!(f.is_empty(), "{f:?}");
        assert_eq!(updated, allow);
        let allow = parse_allowlist("125 a/src/lib.rs long\n").unwrap();
        let (f, updated) = check_lengths(&long, &allow);
        assert!(f[0].message.contains("grew to 130"), "{}", f[0]);
        assert_eq!(updated, allow, "never raised");
    }

    #[test]
    fn a_pub_fn_taking_a_clap_struct_is_flagged_but_an_entry_point_run_is_not() {
        let src = r#"
            #[derive(clap::Args, Debug)]
            pub struct XArgs { pub a: u32 }
            #[derive(Parser)]
            struct YArgs;
            #[derive(Debug, Clone)]
            pub struct XOptions { pub a: u32 }
            pub fn run(args: XArgs) {}
            pub fn load(args: &XArgs, stream: bool) {}
            pub(crate) fn internal(args: &XArgs) {}
            fn private(args: &XArgs) {}
            pub fn typed(o: &XOptions) {}
            pub fn inside(o: Option<&cli::YArgs>) {}
            impl XArgs { pub fn to_options(&self) -> XOptions { XOptions { a: self.a } } }
            impl Thing { pub fn with(&self, a: &XArgs) {} }
            mod m { pub fn run(args: &XArgs) {} }
        "#;
        let args = clap_arg_structs(src).unwrap();
        assert_eq!(args, ["XArgs", "YArgs"]);
        let found: Vec<String> = args_in_library_api(src, &args)
            .unwrap()
            .into_iter()
            .map(|(_, _, m)| m.split_whitespace().nth(2).unwrap_or("").to_string())
            .collect();
        assert_eq!(found, ["load", "inside", "with", "run"], "{found:?}");
        let main_rs = "mod cli;\nmod inline { }\nfn main() {}\n";
        assert_eq!(binary_modules(main_rs).unwrap(), ["cli"]);
    }

    #[test]
    fn cfg_test_lines_are_found_and_the_repository_has_none_where_no_harness_runs() {
        let src = "fn f() {}\n\n    #[cfg(test)]\nmod tests {}\n// #[cfg(test)] in a comment\n";
        assert_eq!(cfg_test_lines(src), [3]);
        for (krate, which) in NO_HARNESS {
            let f = check_no_harness(&crate::root(), krate, which).unwrap();
            assert!(f.is_empty(), "{f:?}");
        }
    }

    #[test]
    fn a_shrunk_or_removed_function_lowers_or_drops_its_entry() {
        let allow = parse_allowlist("140 a/src/lib.rs long\n200 a/src/lib.rs gone\n").unwrap();
        let shrunk = measured(&format!("fn long() {}", body(125)));
        let (f, updated) = check_lengths(&shrunk, &allow);
        assert_eq!(f.len(), 2, "{f:?}");
        assert_eq!(
            updated,
            parse_allowlist("125 a/src/lib.rs long\n").unwrap(),
            "lowered, the vanished one dropped"
        );
        let fits = measured(&format!("fn long() {}", body(100)));
        let (_, updated) = check_lengths(&fits, &allow);
        assert!(updated.is_empty());
        assert!(
            parse_allowlist(&render_allowlist(&allow)).unwrap() == allow,
            "the file format round-trips"
        );
    }
}
