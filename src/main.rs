//! The `maaf` command-line tool (every command and option: docs/cli.md): the
//! library's command line with the built-in loss terms ([`maaf::cli::Maaf`]).

fn main() {
    maaf::cli::Maaf::new().run()
}
