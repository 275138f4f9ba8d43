//! Writing to standard output and standard error without panicking.
//!
//! `println!` panics when a write fails ("failed printing to stdout"), e.g. into a full disk
//! or into a pipe whose reader has gone (`| head`). The programs write through [`out`] and
//! [`err`] (or the [`outln!`](crate::outln) and [`errln!`](crate::errln) macros) instead,
//! which return a [`ConsoleError`]; [`exit_status`] turns one into the end of the program: a
//! closed pipe ends it quietly with [`CLOSED_PIPE_STATUS`] (128 + SIGPIPE, what a shell
//! reports for a program killed by SIGPIPE), any other failure is reported on standard error
//! with the program's error status.

use std::fmt;
use std::io::Write;

/// The exit status after a write into a closed pipe: 128 + 13 (SIGPIPE).
pub const CLOSED_PIPE_STATUS: u8 = 141;

/// Standard output or standard error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// Standard output.
    Output,
    /// Standard error.
    Error,
}

impl fmt::Display for Stream {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stream::Output => "standard output",
            Stream::Error => "standard error",
        })
    }
}

/// A write to standard output or standard error that failed.
#[derive(Debug, thiserror::Error)]
#[error("cannot write to {stream}: {source}")]
pub struct ConsoleError {
    /// Where the write went.
    pub stream: Stream,
    /// Why it failed.
    #[source]
    pub source: std::io::Error,
}

impl ConsoleError {
    /// Whether the reader of the stream has gone (a closed pipe): not an error to report.
    pub fn is_closed_pipe(&self) -> bool {
        self.source.kind() == std::io::ErrorKind::BrokenPipe
    }
}

fn write(stream: Stream, args: fmt::Arguments<'_>) -> Result<(), ConsoleError> {
    let result = match stream {
        Stream::Output => {
            let mut lock = std::io::stdout().lock();
            lock.write_fmt(args).and_then(|()| lock.flush())
        }
        Stream::Error => {
            let mut lock = std::io::stderr().lock();
            lock.write_fmt(args).and_then(|()| lock.flush())
        }
    };
    result.map_err(|source| ConsoleError { stream, source })
}

/// Writes `args` to standard output (and flushes it).
pub fn out(args: fmt::Arguments<'_>) -> Result<(), ConsoleError> {
    write(Stream::Output, args)
}

/// Writes `args` to standard error.
pub fn err(args: fmt::Arguments<'_>) -> Result<(), ConsoleError> {
    write(Stream::Error, args)
}

/// Like `println!`, but returns `Result<(), ConsoleError>` instead of panicking.
#[macro_export]
macro_rules! outln {
    () => {
        $crate::console::out(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::console::out(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Like `eprintln!`, but returns `Result<(), ConsoleError>` instead of panicking.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::console::err(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Writes clap's text for a command line that clap did not run (`--help`, `--version`, a usage
/// error) to the stream clap chose, in colour only on a terminal, without panicking. Returns
/// clap's exit status (`fallback` if it does not fit a status byte), or the write that failed.
pub fn write_clap_message(error: &clap::Error, fallback: u8) -> Result<u8, ConsoleError> {
    use std::io::IsTerminal;
    let text = error.render();
    if error.use_stderr() {
        match std::io::stderr().is_terminal() {
            true => err(format_args!("{}", text.ansi())),
            false => err(format_args!("{text}")),
        }?;
    } else {
        match std::io::stdout().is_terminal() {
            true => out(format_args!("{}", text.ansi())),
            false => out(format_args!("{text}")),
        }?;
    }
    Ok(u8::try_from(error.exit_code()).unwrap_or(fallback))
}

/// The exit status after `error` in `program`: [`CLOSED_PIPE_STATUS`] for a closed pipe
/// (nothing is reported), otherwise `status` after `program: error` on standard error (if
/// standard error itself cannot be written, the status is all that is left).
pub fn exit_status(program: &str, error: &dyn fmt::Display, closed_pipe: bool, status: u8) -> u8 {
    if closed_pipe {
        return CLOSED_PIPE_STATUS;
    }
    match errln!("{program}: {error}") {
        Err(failed) if failed.is_closed_pipe() => CLOSED_PIPE_STATUS,
        _ => status,
    }
}
