//! The README and the help, tried as a new user tries them: every shell block of README.md
//! runs in order in an empty folder with the release binary on `PATH`; the output the README
//! shows must still be what the commands print (figures within a tolerance). Then every
//! subcommand's `--help` must end with examples, and every example must run.
//!
//! Lines that need the network, root or a printer (`cargo`, `apt-get`, `sudo`, `lp`, `man`)
//! are not run, and said so; a few examples that take minutes (`bench`, `train`) are only
//! checked to parse.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Grace Hopper's photograph from Debian's python-matplotlib-data (`.ci/run` installs it).
const PHOTO: &str = "/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn have_photo() -> bool {
    if Path::new(PHOTO).exists() {
        return true;
    }
    crate::common::skip(
        "readme (the lines that use the photo)",
        &format!("{PHOTO} is missing (apt-get install python-matplotlib-data)"),
    );
    false
}

/// A fenced block of a Markdown file: its language and text.
struct Block {
    lang: String,
    text: String,
    line: usize,
    /// Only blank lines between this block and the one before.
    follows: bool,
}

fn blocks(md: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut cur: Option<Block> = None;
    let mut follows = false;
    for (i, line) in md.lines().enumerate() {
        match (&mut cur, line.strip_prefix("```")) {
            (None, Some(lang)) => {
                cur = Some(Block {
                    lang: lang.trim().to_string(),
                    text: String::new(),
                    line: i + 1,
                    follows,
                })
            }
            (Some(_), Some(_)) => {
                out.push(cur.take().expect("open block"));
                follows = true;
            }
            (Some(b), None) => {
                b.text.push_str(line);
                b.text.push('\n');
            }
            (None, None) => follows &= line.trim().is_empty(),
        }
    }
    out
}

/// The commands of a shell block: continuation lines joined, blank lines dropped.
fn commands(sh: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for line in sh.lines() {
        if let Some(head) = line.strip_suffix('\\') {
            cur.push_str(head);
            cur.push(' ');
            continue;
        }
        cur.push_str(line);
        if !cur.trim().is_empty() && !cur.trim_start().starts_with('#') {
            out.push(cur.trim().to_string());
        }
        cur.clear();
    }
    out
}

/// Why a command is not run here, if it is not.
fn not_run(cmd: &str) -> Option<&'static str> {
    let first = cmd.split_whitespace().next().unwrap_or("");
    match first {
        "cargo" => Some("builds the project (the tests are that build)"),
        "sudo" | "apt-get" | "apt" | "pip" | "npm" => Some("needs root or the network"),
        _ if cmd.contains("| lp") => Some("needs a printer"),
        _ if cmd.contains("&& man ") || first == "man" => Some("needs man"),
        _ if cmd.contains("$SLURM") => Some("runs inside a Slurm array job"),
        _ => None,
    }
}

/// A fresh folder with the repository's `samples/`, `scenes/` and `docs/` linked in (the
/// README's set-up runs from the repository root) and a home of its own.
fn workdir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for d in ["samples", "scenes", "docs"] {
        std::os::unix::fs::symlink(root().join(d), dir.path().join(d)).unwrap();
    }
    std::fs::create_dir(dir.path().join("home")).unwrap();
    dir
}

fn run(dir: &Path, cmd: &str) -> Output {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_halftone"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    Command::new("bash")
        .args(["-eo", "pipefail", "-c", cmd])
        .current_dir(dir)
        .env("PATH", path)
        .env("HOME", dir.join("home"))
        .env_remove("CLICOLOR_FORCE")
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Whether `actual` shows what `expected` shows: the same words line by line, numbers within
/// 2% (and 0.02), except times (a number before `ms` or `s`), which depend on the machine.
fn same(expected: &str, actual: &str) -> Result<(), String> {
    let exp: Vec<&str> = expected.lines().filter(|l| !l.trim().is_empty()).collect();
    let act: Vec<&str> = actual.lines().filter(|l| !l.trim().is_empty()).collect();
    if exp.len() != act.len() {
        return Err(format!("{} lines shown, {} printed", exp.len(), act.len()));
    }
    for (e, a) in exp.iter().zip(&act) {
        let ew: Vec<&str> = e.split_whitespace().collect();
        let aw: Vec<&str> = a.split_whitespace().collect();
        let bad = || Err(format!("shown:   {e}\nprinted: {a}"));
        if ew.len() != aw.len() {
            return bad();
        }
        for (i, (x, y)) in ew.iter().zip(&aw).enumerate() {
            if x == y {
                continue;
            }
            let (Ok(xv), Ok(yv)) = (x.parse::<f64>(), y.parse::<f64>()) else {
                return bad();
            };
            let time = matches!(ew.get(i + 1), Some(&"ms") | Some(&"s"));
            if !time && (xv - yv).abs() > (0.02 * xv.abs()).max(0.02) {
                return bad();
            }
        }
    }
    Ok(())
}

/// A `text` block of `$ command` lines, each followed by what it prints (on either stream).
fn transcript(file: &str, dir: &Path, block: &Block, failures: &mut Vec<String>) {
    let mut cmd: Option<String> = None;
    let mut shown = String::new();
    let check = |cmd: &str, shown: &str, failures: &mut Vec<String>| {
        let o = run(dir, cmd);
        let printed = format!("{}{}", text(&o), String::from_utf8_lossy(&o.stderr));
        if let Err(e) = same(shown, &printed) {
            failures.push(format!("{file}:{}: $ {cmd}\n{e}", block.line));
        }
    };
    for line in block.text.lines() {
        if let Some(c) = line.strip_prefix("$ ") {
            if let Some(prev) = cmd.take() {
                check(&prev, &shown, failures);
            }
            cmd = Some(c.to_string());
            shown.clear();
        } else {
            shown.push_str(line);
            shown.push('\n');
        }
    }
    if let Some(prev) = cmd {
        check(&prev, &shown, failures);
    }
}

/// Runs the shell blocks of `file` in order in a fresh folder, checking the output blocks.
fn run_markdown(file: &str) {
    let md = std::fs::read_to_string(root().join(file)).unwrap();
    let photo = have_photo();
    let dir = workdir();
    let mut failures = Vec::new();
    let mut last: Option<(String, String)> = None;
    let (mut ran, mut compared) = (0, 0);
    for block in blocks(&md) {
        match block.lang.as_str() {
            "sh" => {
                for cmd in commands(&block.text) {
                    // The set-up's first command is the binary's own first run.
                    let cmd = match cmd.strip_prefix("cargo run --release -- ") {
                        Some(args) => format!("halftone {args}"),
                        None => cmd,
                    };
                    if let Some(why) = not_run(&cmd) {
                        eprintln!("{file}:{}: not run ({why}): {cmd}", block.line);
                        continue;
                    }
                    if !photo && (cmd.contains("photo.jpg") || cmd.contains(PHOTO)) {
                        continue;
                    }
                    let o = if slow(&cmd) {
                        eprintln!("{file}:{}: takes minutes, only parsed: {cmd}", block.line);
                        let args = cmd.split(" #").next().unwrap_or(&cmd);
                        run(dir.path(), &format!("{args} --help >/dev/null"))
                    } else {
                        run(dir.path(), &cmd)
                    };
                    ran += 1;
                    if !o.status.success() {
                        failures.push(format!(
                            "{file}:{}: `{cmd}` failed: {}",
                            block.line,
                            String::from_utf8_lossy(&o.stderr)
                        ));
                    }
                    last = Some((cmd, text(&o)));
                }
            }
            "text" if block.text.starts_with("$ ") => {
                transcript(file, dir.path(), &block, &mut failures);
                compared += 1;
            }
            "text" if block.follows => {
                // The output of the shell block just above: its last command's.
                let Some((cmd, out)) = last.take() else {
                    continue;
                };
                if !photo && cmd.contains("photo.jpg") {
                    continue;
                }
                compared += 1;
                if let Err(e) = same(&block.text, &out) {
                    failures.push(format!("{file}:{}: after `{cmd}`:\n{e}", block.line));
                }
            }
            _ => last = None,
        }
    }
    eprintln!("{file}: ran {ran} commands, compared {compared} outputs");
    assert!(ran >= 10, "{file}: only {ran} commands ran");
    assert!(failures.is_empty(), "\n{}", failures.join("\n\n"));
}

#[test]
fn readme_commands_run_and_print_what_it_shows() {
    let t = std::time::Instant::now();
    run_markdown("README.md");
    eprintln!("README.md took {:.1} s", t.elapsed().as_secs_f64());
}

#[test]
fn the_guide_commands_run_and_print_what_it_shows() {
    let t = std::time::Instant::now();
    run_markdown("docs/guide.md");
    eprintln!("docs/guide.md took {:.1} s", t.elapsed().as_secs_f64());
}

/// Every subcommand path (`convert`, `masks show`, …) from the help's command lists.
fn subcommands(dir: &Path, path: &[String], out: &mut Vec<Vec<String>>) {
    let help = text(&run(dir, &format!("halftone {} --help", path.join(" "))));
    let mut on = false;
    for line in help.lines() {
        if line.starts_with("Commands:") {
            on = true;
            continue;
        }
        if on && line.trim().is_empty() {
            break;
        }
        // A command's own line is indented two spaces; its description's wrapped lines more.
        if on && line.starts_with("  ") && !line.starts_with("   ") {
            let name = line.split_whitespace().next().unwrap_or("").to_string();
            if name.is_empty() || name == "help" {
                continue;
            }
            let mut p = path.to_vec();
            p.push(name);
            out.push(p.clone());
            subcommands(dir, &p, out);
        }
    }
}

/// Small inputs under the names the examples use.
fn fixtures(dir: &Path, photo: bool) {
    let setup = [
        "halftone render raytrace -o photo.png --size 160x120",
        "cp photo.png scan.png && cp photo.png in.png",
        "halftone convert photo.png -o photo.pbm",
        "halftone convert photo.png -o photo-expand.png --method pattern --cell expand",
        "halftone convert photo.png -o photo-4.pgm --levels 4 --device-levels",
        "halftone convert photo.png -o page.pdf --dpi 300",
        "halftone convert photo.png -o frame.png --device spectra6-7in3-v2 --width 160",
        "mkdir -p photos scans in && cp photo.png photos/a.png && cp photo.png scans/a.png && cp photo.png in/a.png",
        "cp scenes/raytrace.toml my-scene.toml",
        "cp fuzz/corpus/ti3/fogra39-solids-and-ramps.ti3 FOGRA39L.ti3 && cp FOGRA39L.ti3 measured.ti3",
    ];
    for cmd in setup {
        let o = run(dir, cmd);
        assert!(
            o.status.success(),
            "{cmd}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    if photo {
        std::fs::copy(PHOTO, dir.join("photo.jpg")).unwrap();
    }
    // A (synthetic) photo of a panel showing its calibration chart beside paper.
    std::fs::copy(
        root().join("docs/calibration/bwry-4in2-photo.png"),
        dir.join("chart-photo.png"),
    )
    .unwrap();
}

/// Examples that take minutes: checked to parse (clap rejects a wrong flag before running)
/// by asking for the help of the same command line.
fn slow(cmd: &str) -> bool {
    // Long runs, a print server that serves until it is stopped, and printing (a printer
    // on the network).
    [
        "halftone bench",
        "halftone train",
        "halftone serve",
        "halftone print",
    ]
    .iter()
    .any(|s| cmd.starts_with(s))
}

#[test]
fn every_help_ends_with_examples_that_run() {
    let photo = have_photo();
    let dir = workdir();
    std::os::unix::fs::symlink(root().join("fuzz"), dir.path().join("fuzz")).unwrap();
    let mut paths = vec![Vec::new()];
    subcommands(dir.path(), &[], &mut paths);
    assert!(paths.len() >= 20, "{paths:?}");
    let mut failures = Vec::new();
    let mut ran = 0;
    for path in &paths {
        // Each page's examples start from the same inputs (an earlier page may have
        // replaced photo.pbm with another size).
        fixtures(dir.path(), photo);
        let name = format!("halftone {}", path.join(" ")).trim().to_string();
        let help = text(&run(dir.path(), &format!("{name} --help")));
        let Some(at) = help.rfind("\nExample") else {
            if !path.is_empty() {
                failures.push(format!("`{name} --help` does not end with examples"));
            }
            continue;
        };
        for line in help[at..].lines().skip(2) {
            let cmd = line.trim();
            if cmd.is_empty() {
                continue;
            }
            // An environment assignment may stand before the command (`VAR=1 halftone …`).
            let first = cmd
                .split_whitespace()
                .find(|w| !(w.contains('=') && w.starts_with(|c: char| c.is_ascii_uppercase())))
                .unwrap_or("");
            if !["halftone", "mkdir", "cat"].contains(&first) {
                failures.push(format!(
                    "`{name} --help`: example line `{cmd}` is not a command (wrapped?)"
                ));
                continue;
            }
            if let Some(why) = not_run(cmd) {
                eprintln!("{name}: not run ({why}): {cmd}");
                continue;
            }
            if !photo && cmd.contains("photo.jpg") {
                continue;
            }
            let cmd = cmd.split(" #").next().unwrap_or(cmd).trim();
            let to_run = if slow(cmd) {
                // The arguments parse (a bad flag or value fails) without the long run.
                format!(
                    "{} --help >/dev/null",
                    cmd.split(" |").next().unwrap_or(cmd)
                )
            } else {
                cmd.to_string()
            };
            let o = run(dir.path(), &to_run);
            ran += 1;
            if !o.status.success() {
                failures.push(format!(
                    "`{name} --help` example `{cmd}` failed: {}",
                    String::from_utf8_lossy(&o.stderr)
                ));
            }
        }
    }
    eprintln!("ran {ran} examples of {} help pages", paths.len());
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn output_comparison_tolerates_figures_not_words() {
    assert!(same("HVS-PSNR 39.98 dB\n", "HVS-PSNR 40.01 dB\n").is_ok());
    assert!(same("HVS-PSNR 39.98 dB\n", "HVS-PSNR 38.00 dB\n").is_err());
    assert!(same("a 6.2 ms\n", "a 60.0 ms\n").is_ok());
    assert!(same("20 method(s)\n", "24 method(s)\n").is_err());
    assert!(same("x\n", "x\ny\n").is_err());
    assert_eq!(commands("a \\\n  b\n# c\n\nd\n"), ["a    b", "d"]);
}

/// The paths docs/ARCHITECTURE.md's tables and recipes name, in backticks or links, are
/// files or folders of the tree (a `NAME` in a path stands for the new file: its folder must
/// exist, as must a glob's), so a recipe cannot go on naming a file that moved.
#[test]
fn architecture_recipes_name_files_that_exist() {
    let md = std::fs::read_to_string(root().join("docs/ARCHITECTURE.md")).unwrap();
    let tops = [
        "src/",
        "python/",
        "web/",
        "presets/",
        "devices/",
        "docs/",
        "scripts/",
        "tests/",
        "kernels/",
        "masks/",
        "palettes/",
        "presses/",
    ];
    let mut names = Vec::new();
    for (i, part) in md.split('`').enumerate() {
        if i % 2 == 1 {
            names.push(part.to_string());
        }
    }
    for link in md.split("](../").skip(1) {
        names.push(link.split(')').next().unwrap_or("").to_string());
    }
    let mut checked = 0;
    let mut missing = Vec::new();
    for name in names {
        let name = name.trim();
        if !tops.iter().any(|t| name.starts_with(t)) || name.contains(' ') {
            continue;
        }
        let path = if name.contains("NAME") || name.contains('*') {
            root().join(name).parent().unwrap().to_path_buf()
        } else {
            root().join(name)
        };
        checked += 1;
        if !path.exists() {
            missing.push(name.to_string());
        }
    }
    assert!(
        checked >= 20,
        "only {checked} paths found in docs/ARCHITECTURE.md"
    );
    assert!(
        missing.is_empty(),
        "docs/ARCHITECTURE.md names paths that are not in the tree: {missing:?}"
    );
}

/// The README stays a front page: details go to docs/.
#[test]
fn readme_is_at_most_250_lines() {
    let md = std::fs::read_to_string(root().join("README.md")).unwrap();
    let n = md.lines().count();
    assert!(n <= 250, "README.md has {n} lines; move details to docs/");
}
