//! Flags the chosen method or format would ignore are errors, not silent no-ops: one table
//! says which methods and formats use each flag. A new flag is one line in [`RULES`].

use clap::parser::ValueSource;
use clap::ArgMatches;

use halftone::io::Format;

use halftone::MethodKind;

/// What a flag's use depends on.
#[derive(Clone, Copy, Debug)]
pub enum UsedBy {
    /// Only these methods read it.
    Methods(&'static [MethodKind]),
    /// Only these output formats read it.
    Formats(&'static [Format]),
    /// Any method or format, but not together with this other flag (`(id, flag)`), which
    /// takes over its job.
    NotWith(&'static str, &'static str),
}

/// One row of the table: the clap id of a flag, how it is written, and who uses it.
#[derive(Clone, Copy, Debug)]
pub struct Rule {
    /// The argument's id in clap (the field name).
    pub id: &'static str,
    /// The flag as written on the command line.
    pub flag: &'static str,
    /// The methods or formats that read it.
    pub used_by: UsedBy,
}

use MethodKind::{Dbs, Diffuse, Ordered, Pattern, Screen, Threshold};

/// Which methods and formats use which flags.
pub const RULES: &[Rule] = &[
    rule("mask", "--mask", UsedBy::Methods(&[Pattern, Ordered])),
    rule("cell", "--cell", UsedBy::Methods(&[Pattern])),
    rule("threshold", "--threshold", UsedBy::Methods(&[Threshold])),
    rule("kernel", "--kernel", UsedBy::Methods(&[Diffuse])),
    rule("strength", "--strength", UsedBy::Methods(&[Diffuse])),
    rule("serpentine", "--serpentine", UsedBy::Methods(&[Diffuse])),
    rule(
        "no_serpentine",
        "--no-serpentine",
        UsedBy::Methods(&[Diffuse]),
    ),
    rule("seed", "--seed", UsedBy::Methods(&[Diffuse])),
    rule(
        "palette",
        "--palette",
        UsedBy::Methods(&[Diffuse, Dbs, Ordered]),
    ),
    rule(
        "device",
        "--device",
        UsedBy::Methods(&[Diffuse, Dbs, Ordered]),
    ),
    rule("passes", "--passes", UsedBy::Methods(&[Dbs])),
    rule("distance", "--distance", UsedBy::Methods(&[Dbs])),
    rule(
        "no_tone_correction",
        "--no-tone-correction",
        UsedBy::Methods(&[Dbs]),
    ),
    rule("hysteresis", "--hysteresis", UsedBy::Methods(&[Diffuse])),
    rule("printer_model", "--printer-model", UsedBy::Methods(&[Dbs])),
    rule("dot_ratio", "--dot-ratio", UsedBy::Methods(&[Dbs])),
    rule("printer_table", "--printer-table", UsedBy::Methods(&[Dbs])),
    rule("lpi", "--lpi", UsedBy::Methods(&[Screen])),
    rule("angle", "--angle", UsedBy::Methods(&[Screen])),
    rule("angles", "--angles", UsedBy::Methods(&[Screen])),
    rule("spot", "--spot", UsedBy::Methods(&[Screen])),
    rule("gcr", "--gcr", UsedBy::NotWith("icc", "--icc")),
    rule("tac", "--tac", UsedBy::NotWith("icc", "--icc")),
    rule("press", "--press", UsedBy::NotWith("icc", "--icc")),
    rule(
        "separation",
        "--separation",
        UsedBy::NotWith("icc", "--icc"),
    ),
    rule(
        "maxval",
        "--maxval",
        UsedBy::Formats(&[Format::Pgm, Format::Ppm]),
    ),
    rule(
        "compression",
        "--compression",
        UsedBy::Formats(&[Format::Tiff, Format::Pdf]),
    ),
    rule(
        "device_levels",
        "--device-levels",
        UsedBy::Formats(&[Format::Pgm, Format::Ppm, Format::Png]),
    ),
    rule(
        "page",
        "--page",
        UsedBy::Formats(&[Format::Pdf, Format::Ps, Format::Pcl]),
    ),
    rule(
        "band_rows",
        "--band-rows",
        UsedBy::Formats(&[Format::EscPos]),
    ),
    rule("cut", "--cut", UsedBy::Formats(&[Format::EscPos])),
    rule(
        "paper_width",
        "--paper-width",
        UsedBy::Formats(&[Format::EscPos]),
    ),
    rule(
        "zpl_encoding",
        "--zpl-encoding",
        UsedBy::Formats(&[Format::Zpl]),
    ),
    rule(
        "max_length",
        "--max-length",
        UsedBy::Formats(&[Format::Zpl]),
    ),
];

const fn rule(id: &'static str, flag: &'static str, used_by: UsedBy) -> Rule {
    Rule { id, flag, used_by }
}

fn method_name(m: MethodKind) -> &'static str {
    match m {
        Threshold => "threshold",
        Pattern => "pattern",
        Ordered => "ordered",
        Diffuse => "diffuse",
        Dbs => "dbs",
        Screen => "screen",
    }
}

fn format_name(f: Format) -> String {
    format!("{f:?}").to_ascii_uppercase()
}

/// Fails on the first flag given on the command line that `method` or `format` ignores
/// (`format` is `None` when it is not known yet, e.g. per file in a batch).
pub fn check_used(
    matches: &ArgMatches,
    method: MethodKind,
    format: Option<Format>,
) -> anyhow::Result<()> {
    for r in RULES {
        let given = matches.try_get_raw(r.id).ok().flatten().is_some()
            && matches.value_source(r.id) == Some(ValueSource::CommandLine);
        if !given {
            continue;
        }
        match r.used_by {
            UsedBy::Methods(ms) if !ms.contains(&method) => {
                let users: Vec<&str> = ms.iter().map(|&m| method_name(m)).collect();
                anyhow::bail!(
                    "{}: the {} method does not use it (it is for --method {}); leave it out \
                     or choose that method",
                    r.flag,
                    method_name(method),
                    users.join(" or ")
                );
            }
            UsedBy::NotWith(id, flag) if matches.try_get_raw(id).ok().flatten().is_some() => {
                anyhow::bail!(
                    "{}: {flag} decides it (the profile's own black generation, ink limit and \
                     separation); leave one of them out",
                    r.flag
                );
            }
            UsedBy::Formats(fs) => match format {
                Some(f) if !fs.contains(&f) => {
                    let users: Vec<String> = fs.iter().map(|&f| format_name(f)).collect();
                    anyhow::bail!(
                        "{}: {} output does not use it (it is for {} output)",
                        r.flag,
                        format_name(f),
                        users.join(" or ")
                    );
                }
                _ => {}
            },
            _ => {}
        }
    }
    Ok(())
}
