//! The `pathtracer` command line: rendering with the course's flags (`-t -s -l -m -H -f -r -a`),
//! and the `bench`, `compare`, `converge`, `gen`, `chart`, `merge`, `part-info` and
//! `completions` subcommands, parsed by clap (`cli::command`), then calls the library. It
//! first hands over to the build for the best instruction set the CPU runs (`cli::launch`). Every
//! user error is one line on stderr and exit code 2; nothing is written unless the render
//! succeeded. All output goes through `cli::write_stdout` / `write_stderr` (never `println!`,
//! which panics on a full or closed stdout).

use std::process::ExitCode;

mod cli;

fn main() -> ExitCode {
    // Before anything else: the build for the best instruction set this CPU runs may replace
    // this process (src/cli/launch.rs).
    if let Err(e) = cli::launch::run_chosen_build() {
        return cli::exit_code(Err(e));
    }
    // First, while this is the only thread: the signal mask is inherited by every later one.
    cli::signals::remove_temporaries_on_signals();
    cli::exit_code(cli::command::run(std::env::args_os()))
}
