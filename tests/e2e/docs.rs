//! The documentation's command blocks, run as a new user pastes them: a README whose commands rot
//! is worse than none.
//!
//! **Pages.** `README.md`, `docs/examples/README.md` and every `docs/guide/*.md`, one test each
//! ([`every_page_has_a_test`] fails when a page has none). Relative links in those pages and in
//! `docs/formats.md`, `docs/ARCHITECTURE.md`, `CONTRIBUTING.md` and the crates' READMEs must name
//! files that exist ([`relative_links_name_existing_files`]).
//!
//! **Layout.** Each page runs in its own fresh copy of the repository (a guide page after the
//! guide index's blocks: its set-up, which every guide page assumes): the files `git ls-files`
//! lists (what a clone holds; without git, the working tree minus `target*/`, `out/`, `.git/`),
//! copied to a temporary `T/handclasp`. When a shared data folder is found (`../shared/data`
//! beside the workspace, as in CI, or `/work/shared/data`), `T/shared/data` links to it, so that
//! `../shared/data` in a block means what it means in a clone. The page's ```` ```sh ```` blocks
//! run in order in `T/handclasp`, each as one `bash -euo pipefail` script, so a block fails when
//! any of its commands fails (a missing input file included); the test fails with the page, the
//! block's line, the command and its output.
//!
//! **Commands.** `PATH` starts with `T/bin`, which holds links named `handclasp`, `sim-cell` and
//! (when built) `ctu-motoman` to the binaries cargo built for this test run (the test profile;
//! the docs' `--release` builds run the same code faster), and a `cargo` script that maps
//! - `cargo run --release --bin handclasp -- ARGS` → `handclasp ARGS`,
//! - `cargo run --release -p sim-cell -- ARGS` → `sim-cell ARGS`,
//! - `cargo run --release -p ctu-motoman -- ARGS` → `ctu-motoman ARGS`,
//! - `cargo install --path DIR [--locked]` → nothing (DIR must hold a `Cargo.toml`; the links
//!   above are what it installs), `cargo test --workspace` → nothing (this test runs inside it),
//!   `cargo build --release …` → nothing (the links stand for the release binaries),
//!
//! each no-op saying so on stderr, and fails on any other cargo command. `handclasp` is the
//! binary of this package (`CARGO_BIN_EXE_handclasp`); `sim-cell` and `ctu-motoman` are its
//! siblings in the same target folder, which `cargo test --workspace` builds (their packages
//! have integration tests). Run alone (`cargo test -p handclasp --test e2e docs`), build them
//! first (`cargo build -p sim-cell`), else the page fails naming the missing binary.
//!
//! **Annotations** (an HTML comment on the line before a fence, invisible on GitHub):
//! - `<!-- docs-test: skip REASON -->` before a ```` ```sh ```` block: not run; the reason (which
//!   must say how the block is covered otherwise) is printed. For blocks that need the network
//!   or a release build.
//! - `<!-- docs-test: output -->` before a ```` ```text ```` block: a sample of what the previous
//!   ```` ```sh ```` block printed. Its lines, except `…` lines, must appear in that block's
//!   output (stdout, then stderr) in the same order, so the sample stays true.
//!
//! A block that names `../shared/data` runs when the data folder is found and is skipped with a
//! printed reason otherwise (CI has it); keep whatever uses its outputs in the same block.
//! Fences named `bash`, `shell`, `console`, `zsh` or `shell-session` are refused: a command block
//! is ```` ```sh ````, so that this test sees it. Each block's wall time is printed
//! (`cargo test … -- --nocapture`).

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::support::workspace;

/// One fenced block of a Markdown page.
#[derive(Debug)]
struct Block {
    /// 1-based line of the opening fence.
    line: usize,
    /// The fence's info string (`sh`, `text`, `toml`, …), first word.
    lang: String,
    /// The `docs-test:` annotation on the line before the fence, if any.
    annotation: Option<String>,
    /// The block's text, fences excluded.
    text: String,
}

/// The fenced blocks of `markdown`, in order. Panics (naming the page and line) on an unclosed
/// fence.
fn blocks(markdown: &str, page: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut open: Option<Block> = None;
    let mut previous_line = "";
    for (i, line) in markdown.lines().enumerate() {
        let trimmed = line.trim_start();
        match &mut open {
            Some(b) => {
                if trimmed.starts_with("```") && trimmed.trim_end() == "```" {
                    out.push(open.take().expect("open block"));
                } else {
                    b.text.push_str(line);
                    b.text.push('\n');
                }
            }
            None => {
                if let Some(info) = trimmed.strip_prefix("```") {
                    let annotation = previous_line
                        .trim()
                        .strip_prefix("<!-- docs-test:")
                        .and_then(|a| a.strip_suffix("-->"))
                        .map(|a| a.trim().to_string());
                    open = Some(Block {
                        line: i + 1,
                        lang: info.split_whitespace().next().unwrap_or("").to_string(),
                        annotation,
                        text: String::new(),
                    });
                }
            }
        }
        if !line.trim().is_empty() {
            previous_line = line;
        }
    }
    if let Some(b) = open {
        panic!("{page}:{}: the ```{} fence is never closed", b.line, b.lang);
    }
    out
}

/// Fence names that would hide a command block from this test.
const REFUSED_LANGS: [&str; 5] = ["bash", "shell", "console", "zsh", "shell-session"];

/// The shared data folder a clone's `../shared/data` would be, if any holds the CTU dataset.
fn shared_data() -> Option<PathBuf> {
    [
        workspace("../shared/data"),
        PathBuf::from("/work/shared/data"),
    ]
    .into_iter()
    .find(|d| d.join("ctu-motoman/README.md").is_file())
}

/// The files of a fresh clone, relative to the workspace root.
fn clone_files() -> Vec<PathBuf> {
    let root = workspace("");
    let git = Command::new("git")
        .args(["ls-files", "-z", "--cached"])
        .current_dir(&root)
        .output();
    if let Ok(out) = git {
        if out.status.success() && !out.stdout.is_empty() {
            return out
                .stdout
                .split(|b| *b == 0)
                .filter(|p| !p.is_empty())
                .map(|p| PathBuf::from(String::from_utf8_lossy(p).into_owned()))
                // A file deleted in the working tree but not yet from the index is not in a clone
                // of the next commit either.
                .filter(|p| root.join(p).is_file())
                .collect();
        }
    }
    let mut files = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        for entry in std::fs::read_dir(root.join(&rel)).expect("read the workspace") {
            let entry = entry.expect("a directory entry");
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = rel.join(&name);
            let kind = entry.file_type().expect("file type");
            if kind.is_dir() {
                let skip = name == ".git" || name == "out" || name.starts_with("target");
                if !skip {
                    stack.push(path);
                }
            } else if kind.is_file() {
                files.push(path);
            }
        }
    }
    files
}

/// The `cargo` stand-in (see the module documentation). `$1…` are cargo's arguments.
const CARGO_SHIM: &str = r#"#!/bin/sh
# docs test: cargo as the documentation uses it, mapped to the binaries of this test run.
if [ "$1 $2" = "run --release" ] && [ "$5" = "--" ]; then
  case "$3 $4" in
    "--bin handclasp") shift 5; exec handclasp "$@" ;;
    "-p sim-cell") shift 5; exec sim-cell "$@" ;;
    "-p ctu-motoman") shift 5; exec ctu-motoman "$@" ;;
  esac
fi
if [ "$1 $2" = "install --path" ]; then
  if [ -f "$3/Cargo.toml" ]; then
    echo "docs test: not run: cargo install --path $3 (PATH already holds the test build of its binary)" >&2
    exit 0
  fi
  echo "docs test: cargo install --path $3: no Cargo.toml there" >&2
  exit 1
fi
if [ "$*" = "test --workspace" ] || [ "$*" = "test --workspace --locked" ]; then
  echo "docs test: not run: cargo $* (this test runs inside it)" >&2
  exit 0
fi
if [ "$1 $2" = "build --release" ]; then
  echo "docs test: not run: cargo $* (PATH holds the test builds of the binaries)" >&2
  exit 0
fi
echo "docs test: \`cargo $*\` is not mapped to a binary of this test run; map it in tests/e2e/docs.rs or write a command the test knows" >&2
exit 1
"#;

/// The binaries the `bin/` links point at: (name, path). `ctu-motoman` only when it is built.
fn binaries() -> Vec<(&'static str, PathBuf)> {
    let handclasp = PathBuf::from(env!("CARGO_BIN_EXE_handclasp"));
    let dir = handclasp.parent().expect("target folder").to_path_buf();
    let sibling = |name: &str| dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    let mut out = vec![("handclasp", handclasp), ("sim-cell", sibling("sim-cell"))];
    let ctu = sibling("ctu-motoman");
    if ctu.is_file() {
        out.push(("ctu-motoman", ctu));
    }
    out
}

/// A fresh clone of the workspace in a temporary folder, with `bin/` and `shared/data`.
struct Clone {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    bin: PathBuf,
}

fn fresh_clone() -> Clone {
    let tmp = tempfile::tempdir().expect("temporary folder");
    let root = tmp.path().join("handclasp");
    let from = workspace("");
    for rel in clone_files() {
        let to = root.join(&rel);
        std::fs::create_dir_all(to.parent().expect("a parent")).expect("create a folder");
        std::fs::copy(from.join(&rel), &to)
            .unwrap_or_else(|e| panic!("copy {}: {e}", rel.display()));
    }
    let bin = tmp.path().join("bin");
    std::fs::create_dir_all(&bin).expect("bin folder");
    for (name, path) in binaries() {
        assert!(
            path.is_file(),
            "the `{name}` binary is not built ({}): `cargo test --workspace` builds it; run alone, \
             build it first (`cargo build -p {name}`)",
            path.display()
        );
        symlink(&path, &bin.join(name));
    }
    let cargo = bin.join("cargo");
    std::fs::write(&cargo, CARGO_SHIM).expect("write the cargo shim");
    make_executable(&cargo);
    if let Some(data) = shared_data() {
        std::fs::create_dir_all(tmp.path().join("shared")).expect("shared folder");
        symlink(&data, &tmp.path().join("shared/data"));
    }
    Clone {
        _tmp: tmp,
        root,
        bin,
    }
}

#[cfg(unix)]
fn symlink(target: &Path, link: &Path) {
    std::os::unix::fs::symlink(target, link)
        .unwrap_or_else(|e| panic!("link {} → {}: {e}", link.display(), target.display()));
}

#[cfg(unix)]
fn make_executable(path: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).expect("chmod");
}

/// What one run of a block printed.
struct Ran {
    stdout: String,
    stderr: String,
}

/// Runs `script` with bash in `clone`, failing the test with `place` and the output when it
/// fails.
fn run_block(clone: &Clone, place: &str, script: &str) -> Ran {
    let path = std::env::var_os("PATH").unwrap_or_default();
    let mut paths = vec![clone.bin.clone()];
    paths.extend(std::env::split_paths(&path));
    let full = format!("trap 'echo \"docs test: failed: $BASH_COMMAND\" >&2' ERR\n{script}");
    let start = Instant::now();
    let out = Command::new("bash")
        .args(["--noprofile", "--norc", "-euo", "pipefail", "-c", &full])
        .current_dir(&clone.root)
        .env("PATH", std::env::join_paths(paths).expect("PATH"))
        .env("NO_COLOR", "1")
        .env_remove("CTU_MOTOMAN_DATA")
        .output()
        .expect("runs bash");
    let ran = Ran {
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    };
    eprintln!("{place}: ran in {:.1} s", start.elapsed().as_secs_f64());
    assert!(
        out.status.success(),
        "{place}: the block failed ({}):\n--- block\n{script}--- stdout (last 40 lines)\n{}\n--- stderr (last 40 lines)\n{}",
        out.status,
        tail(&ran.stdout, 40),
        tail(&ran.stderr, 40)
    );
    ran
}

fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// Checks that the sample `sample`'s lines (`…` lines left out) appear in `ran`'s output in
/// order; panics at `place` naming the first line that does not.
fn check_output_sample(place: &str, sample: &str, ran: &Ran) {
    let printed: Vec<&str> = ran
        .stdout
        .lines()
        .chain(ran.stderr.lines())
        .map(str::trim_end)
        .collect();
    let mut at = 0;
    for want in sample.lines().map(str::trim_end) {
        if want.trim() == "…" || want.trim().is_empty() {
            continue;
        }
        match printed[at..].iter().position(|p| *p == want) {
            Some(k) => at += k + 1,
            None => panic!(
                "{place}: the output sample's line\n  {want}\nis not (in this order) in what the block printed:\n{}",
                printed.join("\n")
            ),
        }
    }
}

/// The guide's index, whose set-up block (install, `mkdir -p out`) every guide page assumes.
const GUIDE_INDEX: &str = "docs/guide/README.md";

/// Runs the command blocks of `page` (relative to the workspace root) in a fresh clone; for a
/// page of the guide, after those of [`GUIDE_INDEX`].
fn run_page(page: &str) {
    let clone = fresh_clone();
    if page.starts_with("docs/guide/") && page != GUIDE_INDEX {
        run_blocks(&clone, GUIDE_INDEX);
    }
    run_blocks(&clone, page);
}

/// Runs the command blocks of `page` in order in `clone`, checking output samples and
/// annotations, and prints what ran and what was skipped.
fn run_blocks(clone: &Clone, page: &str) {
    let text =
        std::fs::read_to_string(workspace(page)).unwrap_or_else(|e| panic!("read {page}: {e}"));
    let blocks = blocks(&text, page);
    let data = shared_data();
    let mut last: Option<(String, Ran)> = None;
    let mut report = String::new();
    let mut commands = 0;
    for b in &blocks {
        let place = format!("{page}:{}", b.line);
        assert!(
            !REFUSED_LANGS.contains(&b.lang.as_str()),
            "{place}: a command block is ```sh (so that tests/e2e/docs.rs runs it), not ```{}",
            b.lang
        );
        match (b.lang.as_str(), b.annotation.as_deref()) {
            ("sh", None) => {
                if b.text.contains("../shared/data") && data.is_none() {
                    let _ = writeln!(
                        report,
                        "{place}: skipped: it reads ../shared/data, and no shared data folder \
                         is beside the workspace (CI has one)"
                    );
                    last = None;
                    continue;
                }
                commands += 1;
                let ran = run_block(clone, &place, &b.text);
                last = Some((place, ran));
            }
            ("sh", Some(a)) if a.starts_with("skip") => {
                let reason = a["skip".len()..].trim();
                assert!(
                    !reason.is_empty(),
                    "{place}: `docs-test: skip` needs a reason saying how the block is covered"
                );
                let _ = writeln!(report, "{place}: skipped: {reason}");
                last = None;
            }
            ("text", Some("output")) => {
                let (from, ran) = last.as_ref().unwrap_or_else(|| {
                    panic!("{place}: an output sample must follow a ```sh block that ran")
                });
                check_output_sample(&format!("{place} (output of {from})"), &b.text, ran);
            }
            (_, Some(a)) => panic!(
                "{place}: unknown annotation `docs-test: {a}` on a ```{} block (use `skip REASON` \
                 on ```sh or `output` on ```text)",
                b.lang
            ),
            (_, None) => {}
        }
    }
    eprintln!("{page}: {commands} command block(s) ran\n{report}");
}

/// The pages whose command blocks run, relative to the workspace root.
fn pages() -> BTreeSet<String> {
    let mut pages: BTreeSet<String> = ["README.md", "docs/examples/README.md"]
        .into_iter()
        .map(String::from)
        .collect();
    for entry in std::fs::read_dir(workspace("docs/guide")).expect("docs/guide") {
        let name = entry
            .expect("entry")
            .file_name()
            .to_string_lossy()
            .into_owned();
        if name.ends_with(".md") {
            pages.insert(format!("docs/guide/{name}"));
        }
    }
    pages
}

/// One test per page, so that pages run in parallel and a failure names its page.
macro_rules! page_tests {
    ($($name:ident => $page:literal,)*) => {
        $(
            #[test]
            fn $name() {
                run_page($page);
            }
        )*
        /// The pages [`page_tests!`] covers.
        const TESTED_PAGES: &[&str] = &[$($page),*];
    };
}

page_tests! {
    readme => "README.md",
    examples_readme => "docs/examples/README.md",
    guide_index => "docs/guide/README.md",
    guide_models => "docs/guide/models.md",
    guide_calibrate_points => "docs/guide/calibrate-points.md",
    guide_calibrate_cell => "docs/guide/calibrate-cell.md",
    guide_one_robot => "docs/guide/one-robot.md",
    guide_plan => "docs/guide/plan.md",
    guide_diagnose => "docs/guide/diagnose.md",
    guide_import => "docs/guide/import.md",
    guide_export => "docs/guide/export.md",
    guide_report => "docs/guide/report.md",
    guide_simulate => "docs/guide/simulate.md",
    guide_real_data => "docs/guide/real-data.md",
    guide_validate => "docs/guide/validate.md",
    guide_python => "docs/guide/python.md",
    guide_warnings => "docs/guide/warnings.md",
}

#[test]
fn every_page_has_a_test() {
    let tested: BTreeSet<String> = TESTED_PAGES.iter().map(|p| p.to_string()).collect();
    assert_eq!(
        pages(),
        tested,
        "every page whose blocks run needs a line in `page_tests!` (tests/e2e/docs.rs)"
    );
}

/// The Markdown pages whose relative links are checked.
fn linked_pages() -> Vec<String> {
    let mut pages: Vec<String> = pages().into_iter().collect();
    pages.extend(
        ["docs/formats.md", "docs/ARCHITECTURE.md", "CONTRIBUTING.md"]
            .into_iter()
            .map(String::from),
    );
    for entry in std::fs::read_dir(workspace("crates")).expect("crates") {
        let readme = entry.expect("entry").path().join("README.md");
        if readme.is_file() {
            let name = readme
                .strip_prefix(workspace(""))
                .unwrap_or(&readme)
                .to_string_lossy()
                .into_owned();
            pages.push(name);
        }
    }
    pages
}

/// The relative link targets of `markdown` (`[text](target)`), without `#anchors`, outside
/// fenced blocks and code spans; web and mail links left out.
fn relative_links(markdown: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut in_fence = false;
    for (i, line) in markdown.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence {
            continue;
        }
        // Drop code spans, where `](` is text.
        let mut plain = String::new();
        for (k, part) in line.split('`').enumerate() {
            if k % 2 == 0 {
                plain.push_str(part);
            }
        }
        let mut rest = plain.as_str();
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let Some(end) = rest.find(')') else { break };
            let target = rest[..end].split_whitespace().next().unwrap_or("");
            let path = target.split('#').next().unwrap_or("");
            let external = path.contains("://") || path.starts_with("mailto:");
            if !path.is_empty() && !external {
                out.push((i + 1, path.to_string()));
            }
            rest = &rest[end..];
        }
    }
    out
}

#[test]
fn relative_links_name_existing_files() {
    let mut broken = Vec::new();
    for page in linked_pages() {
        let path = workspace(&page);
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("read {page}: {e}"));
        let dir = path.parent().expect("a folder");
        for (line, target) in relative_links(&text) {
            if dir.join(&target).exists() {
                continue;
            }
            broken.push(format!("{page}:{line}: {target}"));
        }
    }
    assert!(
        broken.is_empty(),
        "links to files that do not exist:\n{}",
        broken.join("\n")
    );
}

#[test]
fn the_parsers_find_blocks_annotations_and_links() {
    let page = "text\n<!-- docs-test: skip needs the network -->\n\n```sh\necho a\n```\n\
                [x](docs/a.md#b) `[y](not/a/link)` [w](https://x.org)\n```toml\nk = 1\n```\n";
    let b = blocks(page, "p");
    assert_eq!(b.len(), 2);
    assert_eq!(
        (b[0].line, b[0].lang.as_str(), b[0].text.as_str()),
        (4, "sh", "echo a\n")
    );
    assert_eq!(b[0].annotation.as_deref(), Some("skip needs the network"));
    assert_eq!(
        (b[1].lang.as_str(), b[1].annotation.as_deref()),
        ("toml", None)
    );
    assert_eq!(relative_links(page), vec![(7, "docs/a.md".to_string())]);
}

#[test]
fn an_output_sample_must_be_what_the_block_printed() {
    let ran = Ran {
        stdout: "a\nb  \nc\n".into(),
        stderr: "d\n".into(),
    };
    check_output_sample("p", "a\n…\nc\nd\n", &ran);
    let wrong = std::panic::catch_unwind(|| check_output_sample("p", "c\na\n", &ran));
    assert!(wrong.is_err(), "out of order must fail");
    let missing = std::panic::catch_unwind(|| check_output_sample("p", "e\n", &ran));
    assert!(missing.is_err(), "a line never printed must fail");
}
