//! The command line's option flags, generated from the library's one option table
//! (`halftone::options::describe`): each option's flag, value name, help, default and
//! parser come from there, and the values given go through `Settings`, as every other
//! door's do. The command line adds only what is a process's own: `--preview FILE`, where a
//! CMYK preview is written, and the output's `--format` (with `-o`).

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, ValueParser};
use clap::parser::ValueSource;
use clap::{Arg, ArgAction, ArgMatches, Args, Command, FromArgMatches};

use halftone::options::table::{Choices, Form, OptionSpec};
use halftone::options::{describe, Settings, Value};
use halftone::Options;

/// The clap argument(s) of one option.
fn args_of(spec: &'static OptionSpec) -> Vec<Arg> {
    let mut help = spec.help.to_string();
    let long: &'static str = Box::leak(spec.flag().into_boxed_str());
    match spec.form {
        Form::Door => Vec::new(),
        Form::Switch => vec![Arg::new(spec.name)
            .long(long)
            .action(ArgAction::SetTrue)
            .help(help)],
        Form::Negative(flag) => vec![Arg::new(spec.name)
            .long(flag)
            .action(ArgAction::SetTrue)
            .help(help)],
        Form::Both(flag) => {
            let neg: &'static str = Box::leak(flag.replace('-', "_").into_boxed_str());
            vec![
                Arg::new(spec.name)
                    .long(long)
                    .action(ArgAction::SetTrue)
                    .overrides_with(neg)
                    .help(help),
                Arg::new(neg)
                    .long(flag)
                    .action(ArgAction::SetTrue)
                    .overrides_with(spec.name)
                    .help(format!("Opposite of --{long}")),
            ]
        }
        Form::Value => {
            let mut arg = Arg::new(spec.name)
                .long(long)
                .value_name(spec.value_name)
                .action(ArgAction::Set)
                .allow_negative_numbers(true);
            if let Some(c) = spec.short {
                arg = arg.short(c);
            }
            arg = match spec.choices {
                Choices::Fixed(list) => arg.value_parser(PossibleValuesParser::new(
                    list.iter().map(|(n, h)| PossibleValue::new(*n).help(*h)),
                )),
                _ => arg.value_parser(ValueParser::new(move |s: &str| {
                    spec.check(&Value::from(s))
                        .map(|()| s.to_string())
                        .map_err(|e| super::flags_for_options(&e))
                })),
            };
            if let Some(d) = spec.default_text() {
                arg = arg.default_value(&*Box::leak(d.into_boxed_str()));
                if help.contains("[default:") {
                    arg = arg.hide_default_value(true);
                }
            }
            if !help.ends_with('.') && !help.ends_with(']') {
                help.push('.');
            }
            vec![arg.help(help)]
        }
    }
}

/// Adds the flags of the options in `names` (all of them when `None`) to `cmd`.
fn augment(mut cmd: Command, names: Option<&[&str]>) -> Command {
    for spec in describe() {
        if names.is_some_and(|n| !n.contains(&spec.name)) {
            continue;
        }
        for arg in args_of(spec) {
            cmd = cmd.arg(arg);
        }
    }
    cmd
}

fn given(m: &ArgMatches, id: &str) -> bool {
    m.try_get_raw(id).ok().flatten().is_some()
        && m.value_source(id) == Some(ValueSource::CommandLine)
}

/// The options given on the command line among `names` (all when `None`), into
/// `settings`; returns each given option's name as the command line wrote it
/// (`no_tone_correction`), for messages.
fn read(
    m: &ArgMatches,
    names: Option<&[&str]>,
    settings: &mut Settings,
) -> Result<Vec<&'static str>, clap::Error> {
    let mut written = Vec::new();
    let bad = |e: halftone::Error| {
        clap::Error::raw(
            clap::error::ErrorKind::ValueValidation,
            super::flags_for_options(&e.to_string()),
        )
    };
    for spec in describe() {
        if names.is_some_and(|n| !n.contains(&spec.name)) {
            continue;
        }
        match spec.form {
            Form::Door => {}
            Form::Switch => {
                if given(m, spec.name) && m.get_flag(spec.name) {
                    settings.set(spec.name, true).map_err(bad)?;
                    written.push(spec.name);
                }
            }
            Form::Negative(_) => {
                if given(m, spec.name) && m.get_flag(spec.name) {
                    settings.set(spec.name, false).map_err(bad)?;
                    written.push(spec.aliases[0]);
                }
            }
            Form::Both(flag) => {
                let neg = spec.aliases[0];
                debug_assert_eq!(neg, flag.replace('-', "_"));
                if given(m, neg) && m.get_flag(neg) {
                    settings.set(spec.name, false).map_err(bad)?;
                    written.push(neg);
                } else if given(m, spec.name) && m.get_flag(spec.name) {
                    settings.set(spec.name, true).map_err(bad)?;
                    written.push(spec.name);
                }
            }
            Form::Value => {
                if given(m, spec.name) {
                    if let Some(v) = m.get_one::<String>(spec.name) {
                        settings.set(spec.name, v.as_str()).map_err(bad)?;
                        written.push(spec.name);
                    }
                }
            }
        }
    }
    Ok(written)
}

/// Options for reading, tone and writing shared by `convert` and `batch`: every option of
/// the library's table, `--preset`/`--presets`, and `--preview FILE`.
#[derive(Debug, Clone, Default)]
pub struct CommonArgs {
    /// The options given, and the preset chosen.
    settings: Settings,
    /// The given options as the command line wrote them.
    written: Vec<&'static str>,
    /// `--preview FILE.png`: where the CMYK preview goes.
    pub preview: Option<PathBuf>,
}

impl CommonArgs {
    /// The resolved step: the library's options from these flags, then the preset's
    /// values for every option the command line did not give. A preset's format, if it
    /// names one, is in `format`.
    pub fn options(&self) -> anyhow::Result<Options> {
        self.settings
            .clone()
            .finish()
            .map_err(|e| anyhow::anyhow!(super::flags_for_options(&e.to_string())))
    }

    /// The options given and the preset chosen, by their one names with their values (a
    /// print queue re-applies them through `Settings` for every job).
    pub fn given_entries(&self) -> Vec<(String, Value<'static>)> {
        let mut v = Vec::new();
        if let Some(p) = self.settings.preset() {
            v.push(("preset".to_string(), Value::from(p.to_string())));
        }
        for name in self.settings.given() {
            if let Ok(Some(text)) = self.settings.options().get(name) {
                v.push((name.to_string(), Value::from(text)));
            }
        }
        v
    }

    /// Fails on the first option given that the chosen method or `format` does not read.
    pub fn check_used(
        &self,
        opts: &Options,
        format: Option<halftone::Format>,
    ) -> anyhow::Result<()> {
        opts.check_used(&self.written, format)
            .map_err(|e| anyhow::anyhow!(super::flags_for_options(&e.to_string())))
    }
}

impl FromArgMatches for CommonArgs {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut settings = Settings::new();
        let mut written = read(m, None, &mut settings)?;
        if let Some(p) = m.get_one::<String>("preset") {
            settings.set("preset", p.as_str()).ok();
        }
        if let Some(p) = m.get_one::<PathBuf>("presets") {
            settings.set("presets", p.display().to_string()).ok();
        }
        let preview = m.get_one::<PathBuf>("preview").cloned();
        if preview.is_some() {
            settings.set("preview", true).ok();
            written.push("preview");
        }
        Ok(CommonArgs {
            settings,
            written,
            preview,
        })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl Args for CommonArgs {
    fn augment_args(cmd: Command) -> Command {
        augment(cmd, None)
            .arg(Arg::new("preset").long("preset").value_name("PRESET").help(
                "A printer preset (see `halftone presets`); flags given on the command \
                         line win over it",
            ))
            .arg(
                Arg::new("presets")
                    .long("presets")
                    .value_name("FILE")
                    .value_parser(clap::value_parser!(PathBuf))
                    .help("A TOML file of presets adding to (or replacing) the built-ins"),
            )
            .arg(
                Arg::new("preview")
                    .long("preview")
                    .value_name("FILE.png")
                    .value_parser(clap::value_parser!(PathBuf))
                    .help(
                        "Also write what the press would print (through the press model, paper \
                         as white), PNG",
                    ),
            )
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

/// The printer model flags, shared by `compare` and `bench`: the same three options of the
/// table as `convert` takes.
#[derive(Debug, Clone, Default)]
pub struct PrinterArgs {
    options: Options,
}

const PRINTER: &[&str] = &["printer_model", "dot_ratio", "printer_table"];

impl PrinterArgs {
    /// The model asked for, or None for an ideal printer.
    pub fn model(&self) -> anyhow::Result<Option<halftone::printer_model::PrinterModel>> {
        Ok(self.options.printer()?)
    }
}

impl FromArgMatches for PrinterArgs {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut settings = Settings::new();
        read(m, Some(PRINTER), &mut settings)?;
        let options = settings.finish().map_err(|e| {
            clap::Error::raw(clap::error::ErrorKind::ValueValidation, e.to_string())
        })?;
        Ok(PrinterArgs { options })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl Args for PrinterArgs {
    fn augment_args(cmd: Command) -> Command {
        augment(cmd, Some(PRINTER))
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}
