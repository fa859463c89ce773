//! The whole command line as one clap definition: the render command's flags at the top
//! (`pathtracer [OPTIONS] SCENE.dae`, no subcommand word) and the subcommands, each with its
//! generated `--help`; and the mapping of clap's errors to the CLI's one-line `error:`.
//!
//! Only the first argument can name a subcommand (`args_conflicts_with_subcommands`): once a
//! render flag or the scene is read, every later word is the render's, as before clap. A
//! repeated flag takes its last value (`args_override_self`), and a flag's value may begin with
//! `-` (`-r -3 600` is an out-of-range width, not an unknown flag `-3`).

use std::ffi::OsString;

use clap::error::{ContextKind, ContextValue, ErrorKind};
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};

use super::bench::BenchArgs;
use super::chart::ChartCommand;
use super::compare::CompareArgs;
use super::converge::ConvergeArgs;
use super::gen::GenArgs;
use super::merge::{MergeArgs, PartInfoArgs};
use super::render_args::RenderArgs;
use pathtracer::{Error, Result};

/// `pathtracer`: the render command's flags, or one subcommand.
#[derive(Parser, Debug)]
#[command(
    name = "pathtracer",
    version = super::launch::version_text(),
    about = "Renders a CS184 COLLADA scene (course camera and lighting conventions)",
    override_usage = "pathtracer [OPTIONS] SCENE.dae
       pathtracer --info SCENE.dae
       pathtracer --part K/N [OPTIONS] SCENE.dae -f PART.ptpart   (one part of a farm render)
       pathtracer COMMAND ...   (pathtracer COMMAND --help)",
    after_help = "Errors are one line on stderr (error: ...) with exit code 2.",
    args_conflicts_with_subcommands = true,
    disable_help_subcommand = true
)]
pub struct Cli {
    #[command(flatten)]
    render: RenderArgs,
    #[command(subcommand)]
    command: Option<Command>,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    Bench(BenchArgs),
    Compare(CompareArgs),
    Converge(ConvergeArgs),
    Gen(GenArgs),
    /// The charts of PERF.md, drawn as SVG
    #[command(subcommand)]
    Chart(ChartCommand),
    Merge(MergeArgs),
    PartInfo(PartInfoArgs),
    Completions(CompletionsArgs),
}

/// `pathtracer completions SHELL`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Print a shell completion script",
    after_help = "For example: pathtracer completions bash > ~/.local/share/bash-completion/completions/pathtracer"
)]
pub struct CompletionsArgs {
    /// The shell
    #[arg(value_enum, value_name = "SHELL")]
    shell: Shell,
}

/// The shells `completions` writes for.
#[derive(ValueEnum, Clone, Copy, Debug)]
enum Shell {
    Bash,
    Zsh,
    Fish,
}

/// Parses `args` (the program's name first) and runs the command.
pub fn run(args: impl IntoIterator<Item = OsString>) -> Result<()> {
    let args: Vec<OsString> = args.into_iter().collect();
    let cli = match parse_cli(&args)? {
        Parsed::Print(text) => return out!("{text}"),
        Parsed::Run(cli) => *cli,
    };
    match cli.command {
        None => super::render::run(cli.render),
        Some(Command::Bench(a)) => super::bench::run(a),
        Some(Command::Compare(a)) => super::compare::run(a),
        Some(Command::Converge(a)) => super::converge::run(a),
        Some(Command::Gen(a)) => super::gen::run(a),
        Some(Command::Chart(c)) => super::chart::run(c),
        Some(Command::Merge(a)) => super::merge::run(a),
        Some(Command::PartInfo(a)) => super::merge::run_info(a),
        Some(Command::Completions(a)) => completions(a.shell),
    }
}

/// The completion script for `shell`, on stdout.
fn completions(shell: Shell) -> Result<()> {
    let shell = match shell {
        Shell::Bash => clap_complete::Shell::Bash,
        Shell::Zsh => clap_complete::Shell::Zsh,
        Shell::Fish => clap_complete::Shell::Fish,
    };
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut command(), "pathtracer", &mut script);
    out!("{}", String::from_utf8_lossy(&script))
}

/// The clap command with the settings every (sub)command shares.
fn command() -> clap::Command {
    let hide = |a: clap::Arg| a.hide(true);
    common_settings(Cli::command()).mut_subcommand("converge", |c| {
        // The render flags converge refuses (it reports why) stay out of its help.
        c.mut_arg("pixel_samples", hide).mut_arg("output", hide).mut_arg("info", hide)
    })
}

fn common_settings(cmd: clap::Command) -> clap::Command {
    cmd.args_override_self(true)
        .mut_args(|a| {
            if !a.is_positional() && a.get_action().takes_values() {
                a.allow_hyphen_values(true)
            } else {
                a
            }
        })
        .mut_subcommands(common_settings)
}

enum Parsed {
    /// `--help` or `--version`: the text to print.
    Print(String),
    Run(Box<Cli>),
}

fn parse_cli(args: &[OsString]) -> Result<Parsed> {
    let mut cmd = command();
    let path = command_path(&cmd, args);
    let matches = match cmd.try_get_matches_from_mut(args) {
        Ok(m) => m,
        Err(e) => {
            return match e.kind() {
                ErrorKind::DisplayHelp
                | ErrorKind::DisplayVersion
                | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
                    Ok(Parsed::Print(e.to_string()))
                }
                _ => Err(one_line(&e, &cmd, &path)),
            }
        }
    };
    Cli::from_arg_matches(&matches)
        .map(|cli| Parsed::Run(Box::new(cli)))
        .map_err(|e| one_line(&e, &cmd, &path))
}

/// The subcommands `args` names ("", "bench", "chart accuracy"): each is the first word
/// after the program's name or its parent subcommand.
fn command_path(cmd: &clap::Command, args: &[OsString]) -> Vec<String> {
    let mut path = Vec::new();
    let mut cmd = cmd;
    for arg in args.iter().skip(1) {
        match cmd.find_subcommand(arg) {
            Some(sub) => {
                path.push(sub.get_name().to_string());
                cmd = sub;
            }
            None => break,
        }
    }
    path
}

/// A clap error as the CLI's one line (without the `error: ` that `exit_code` adds), naming
/// the flag or argument.
fn one_line(e: &clap::Error, cmd: &clap::Command, path: &[String]) -> Error {
    let context = |kind| match e.get(kind) {
        Some(ContextValue::String(s)) => Some(s.clone()),
        Some(ContextValue::Strings(v)) => Some(v.join(", ")),
        Some(ContextValue::StyledStr(s)) => Some(s.to_string()),
        Some(ContextValue::StyledStrs(v)) => {
            Some(v.iter().map(ToString::to_string).collect::<Vec<_>>().join(", "))
        }
        Some(ContextValue::Number(n)) => Some(n.to_string()),
        _ => None,
    };
    let name = path.join(" ");
    let prefix = if name.is_empty() { String::new() } else { format!("{name}: ") };
    let see =
        if name.is_empty() { "see --help".into() } else { format!("see pathtracer {name} --help") };
    // "--sampler <KIND>" -> "--sampler"; a positional "<SHELL>" stays whole.
    let arg = context(ContextKind::InvalidArg).unwrap_or_default();
    let flag = if arg.starts_with('-') { arg.split([' ', '=']).next().unwrap_or("") } else { &arg };
    let message = match e.kind() {
        ErrorKind::ValueValidation => {
            let source = std::error::Error::source(e);
            match source.and_then(|s| s.downcast_ref::<Error>()) {
                Some(ours) => ours.to_string(), // Our parsers' messages name the flag.
                None => match source {
                    Some(s) => format!("{prefix}{flag}: {s}"),
                    None => fallback(e),
                },
            }
        }
        ErrorKind::InvalidValue => match context(ContextKind::InvalidValue) {
            Some(v) if !v.is_empty() => {
                let what = flag.trim_matches(['<', '>', '[', ']']);
                match context(ContextKind::ValidValue) {
                    Some(valid) => {
                        format!("{prefix}'{v}' is not a valid {what} (expected one of {valid})")
                    }
                    None => format!("{prefix}'{v}' is not a valid {what}"),
                }
            }
            _ => format!("{prefix}{flag} needs a value"),
        },
        ErrorKind::UnknownArgument if arg.starts_with('-') => {
            let tip = match context(ContextKind::SuggestedArg) {
                Some(s) => format!("did you mean '{s}'? "),
                None => String::new(),
            };
            format!("{prefix}unknown option '{arg}' ({tip}{see})")
        }
        // An extra word: clap calls it an unknown argument, or at the top (where a word could
        // have been a subcommand) a subcommand that conflicts with the scene.
        ErrorKind::UnknownArgument | ErrorKind::ArgumentConflict => {
            let word = match e.kind() {
                ErrorKind::UnknownArgument => Some(arg.clone()),
                _ => context(ContextKind::InvalidSubcommand),
            };
            match word {
                Some(w) if matches!(name.as_str(), "" | "bench" | "converge") => {
                    format!("{prefix}more than one scene file given ('{w}' is a second one)")
                }
                Some(w) => format!("{prefix}unexpected argument '{w}' ({see})"),
                None => fallback(e),
            }
        }
        ErrorKind::InvalidSubcommand => {
            let word = context(ContextKind::InvalidSubcommand).unwrap_or_default();
            let parent = path.iter().try_fold(cmd, |c, p| c.find_subcommand(p));
            let names: Vec<&str> =
                parent.map_or(Vec::new(), |c| c.get_subcommands().map(|s| s.get_name()).collect());
            let what = if name == "chart" { "chart" } else { "command" };
            format!("{prefix}unknown {what} '{word}' (expected {})", names.join(" or "))
        }
        ErrorKind::MissingRequiredArgument => format!("{prefix}missing {arg} ({see})"),
        // `-r 800` at the end: name the missing value as a parser would ("-r height").
        ErrorKind::WrongNumberOfValues | ErrorKind::TooFewValues => {
            let names: Vec<&str> =
                arg.split_whitespace().skip(1).map(|n| n.trim_matches(['<', '>'])).collect();
            let given = match e.get(ContextKind::ActualNumValues) {
                Some(ContextValue::Number(n)) => *n as usize,
                _ => 0,
            };
            match names.get(given) {
                Some(&missing) => format!(
                    "{prefix}{flag} {} needs a value ({flag} {})",
                    value_word(missing),
                    names.join(" ")
                ),
                None => fallback(e),
            }
        }
        ErrorKind::InvalidUtf8 => format!("{prefix}an argument is not valid UTF-8"),
        _ => fallback(e),
    };
    Error::new(message)
}

/// The word for a value name in a message: "-r height", "-a tolerance".
fn value_word(name: &str) -> &str {
    match name {
        "W" => "width",
        "H" => "height",
        "B" => "batch",
        "TOL" => "tolerance",
        other => other,
    }
}

/// The first line of clap's own message, without its `error: `.
fn fallback(e: &clap::Error) -> String {
    let text = e.to_string();
    let line = text.lines().next().unwrap_or("invalid arguments");
    line.strip_prefix("error: ").unwrap_or(line).to_string()
}

/// `args` (without the program's name) as a subcommand: for the subcommands' tests.
#[cfg(test)]
pub(super) fn parse(args: &[String]) -> Result<Command> {
    match parse_cli(&with_program(args))? {
        Parsed::Run(cli) => cli.command.ok_or_else(|| Error::new("not a subcommand")),
        Parsed::Print(_) => Err(Error::new("not a subcommand")),
    }
}

/// `args` (without the program's name) as a render command, checked.
#[cfg(test)]
pub(super) fn parse_render(args: &[String]) -> Result<super::render_args::Cli> {
    match parse_cli(&with_program(args))? {
        Parsed::Run(cli) if cli.command.is_none() => cli.render.into_cli(),
        _ => Err(Error::new("not the render command")),
    }
}

#[cfg(test)]
fn with_program(args: &[String]) -> Vec<OsString> {
    std::iter::once("pathtracer")
        .chain(args.iter().map(String::as_str))
        .map(OsString::from)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn the_definition_is_consistent() {
        command().debug_assert();
    }

    #[test]
    fn the_first_word_chooses_the_subcommand() {
        assert!(matches!(parse(&words("bench x.dae")), Ok(Command::Bench(_))));
        assert!(matches!(parse(&words("chart scaling a b")), Ok(Command::Chart(_))));
        // A later word is the render's: a scene named like a subcommand.
        let cli = parse_render(&words("-r 8 6 bench")).unwrap();
        assert_eq!(cli.scene.to_str(), Some("bench"));
        // No `help` subcommand: `pathtracer help` renders a scene named help.
        assert_eq!(parse_render(&words("help")).unwrap().scene.to_str(), Some("help"));
    }

    #[test]
    fn help_and_version_are_printed() {
        for args in ["--help", "-h", "bench --help", "chart", "chart accuracy --help", "merge"] {
            let parsed = parse_cli(&with_program(&words(args))).unwrap_or_else(|e| panic!("{e}"));
            assert!(matches!(&parsed, Parsed::Print(t) if t.contains("Usage:")), "{args}");
        }
        match parse_cli(&with_program(&words("--version"))) {
            Ok(Parsed::Print(t)) => {
                let isa = pathtracer::simd::isa::Isa::compiled();
                let first =
                    format!("pathtracer {}\nisa: {isa} (built for ", env!("CARGO_PKG_VERSION"));
                assert!(t.starts_with(&first), "{t}");
            }
            _ => panic!("--version"),
        }
    }

    #[test]
    fn clap_errors_are_one_line_and_name_the_flag() {
        for (args, want) in [
            ("bench x.dae --threads", "bench: --threads needs a value"),
            ("bench x.dae --threads 0", "--threads: 0 is out of range"),
            ("bench x.dae --ray-set all", "--ray-set: unknown ray set 'all'"),
            ("bench x.dae --frob", "bench: unknown option '--frob'"),
            ("bench a.dae b.dae", "more than one scene"),
            ("chart pie", "chart: unknown chart 'pie' (expected accuracy or scaling)"),
            ("chart scaling a.jsonl", "missing"),
            ("gen cornell 5 6", "gen: unexpected argument '6'"),
            ("completions tcsh", "'tcsh' is not a valid SHELL"),
            ("completions", "completions: missing"),
            ("-f", "-f needs a value"),
            ("--quite x.dae", "did you mean '--quiet'?"),
        ] {
            let err = match parse_cli(&with_program(&words(args))) {
                Err(e) => e.to_string(),
                Ok(Parsed::Run(cli)) if cli.command.is_none() => {
                    cli.render.into_cli().map(|_| ()).unwrap_err().to_string()
                }
                Ok(_) => panic!("{args}: parsed"),
            };
            assert!(err.contains(want), "{args}: got '{err}', want '{want}'");
            assert!(!err.contains('\n'), "{args}: {err}");
        }
    }
}
