//! `halftone options`: every option the command line takes, as the library's one table
//! describes it, and the lists of names (methods, kernels, palettes, …). With `--json`, the
//! form the other doors' parity tests read: the option names here come from the command
//! line's own flags (clap's definition of `convert`), so a flag that went missing or a flag
//! the table does not know shows up as a difference.

use std::collections::BTreeSet;
use std::io::Write;
use std::process::ExitCode;

use clap::Args;

use halftone::options::table::{find, PRESET_NAMES};
use halftone::options::{describe, describe_json, Lists};

/// Arguments of `halftone options`.
#[derive(Args, Debug)]
pub struct OptionsArgs {
    /// Print JSON: `accepts` (the option names `convert` takes), `options` (each option's
    /// flag, values, default, help and the methods or formats that read it) and `lists`.
    #[arg(long)]
    json: bool,
}

/// Examples shown after `halftone options --help`.
pub const EXAMPLES: &str = "Examples:
  halftone options                     # every option: flag, default, values, help
  halftone options --json > options.json  # the same, and the lists, for programs";

/// The option names `convert`'s flags set, one name each as the table writes it (a
/// `--no-…` flag counts as its option), with `preset` and `presets`.
pub fn accepted_by_convert() -> BTreeSet<String> {
    let cmd = super::command();
    let convert = cmd
        .get_subcommands()
        .find(|c| c.get_name() == "convert")
        .expect("convert is a subcommand");
    convert
        .get_arguments()
        .filter_map(|a| a.get_long())
        .filter_map(|long| {
            let name = long.replace('-', "_");
            if PRESET_NAMES.contains(&name.as_str()) {
                Some(name)
            } else {
                find(&name).map(|(spec, _)| spec.name.to_string())
            }
        })
        .collect()
}

/// Runs `halftone options`.
pub fn run(a: OptionsArgs) -> anyhow::Result<ExitCode> {
    let accepts = accepted_by_convert();
    let mut out = std::io::stdout().lock();
    if a.json {
        let doc = serde_json::json!({
            "accepts": accepts,
            "options": describe_json(),
            "lists": Lists::get(),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&doc)?)?;
    } else {
        for s in describe() {
            let default = s.default_text().map(|d| format!(" [default: {d}]"));
            writeln!(out, "--{}{}", s.flag(), default.unwrap_or_default())?;
            let values = s.values();
            if !values.is_empty() {
                writeln!(out, "    values: {}", values.join(", "))?;
            }
            writeln!(out, "    {}", s.help.replace('\n', " "))?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line's flags set every option of the table, and nothing else.
    #[test]
    fn convert_flags_are_the_table() {
        let table: BTreeSet<String> = describe()
            .iter()
            .map(|s| s.name.to_string())
            .chain(PRESET_NAMES.iter().map(|s| s.to_string()))
            .collect();
        assert_eq!(accepted_by_convert(), table);
    }

    /// `convert`'s flags outside the table are the door's own (where the output goes),
    /// so an option written by hand beside the table shows up here.
    #[test]
    fn convert_has_no_option_of_its_own() {
        let cmd = crate::cli::command();
        let convert = cmd
            .get_subcommands()
            .find(|c| c.get_name() == "convert")
            .expect("convert is a subcommand");
        let own: BTreeSet<&str> = convert
            .get_arguments()
            .filter_map(|a| a.get_long())
            .filter(|long| {
                let name = long.replace('-', "_");
                !PRESET_NAMES.contains(&name.as_str()) && find(&name).is_none()
            })
            .collect();
        assert_eq!(own, BTreeSet::from(["output"]));
    }
}
