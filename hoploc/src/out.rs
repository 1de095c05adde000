//! The commands' standard output, written through a handle that notices when its reader has
//! gone.
//!
//! `println!` panics when stdout is a pipe whose reader closed it (`hoploc replay log | head`).
//! [`Out`] writes instead, and when the pipe is closed (`BrokenPipe`) it stops writing and says
//! so ([`Out::closed`]): a command then ends its work quietly, with exit code 0, as the tools of
//! a Unix pipeline do. Any other write error is an error.

use std::fmt;
use std::io::{self, Write};

/// Standard output (or any writer, for tests) that ends quietly on a closed pipe.
pub struct Out<W: Write = io::Stdout> {
    w: W,
    closed: bool,
}

impl Out {
    /// Standard output.
    pub fn stdout() -> Out {
        Out::new(io::stdout())
    }
}

impl<W: Write> Out<W> {
    /// Output to `w`.
    pub fn new(w: W) -> Out<W> {
        Out { w, closed: false }
    }

    /// Whether the reader has gone: nothing more is written, and the caller can stop.
    pub fn closed(&self) -> bool {
        self.closed
    }

    /// Writes `args` (nothing once [`Out::closed`]); a closed pipe is not an error.
    pub fn write(&mut self, args: fmt::Arguments<'_>) -> Result<(), String> {
        if self.closed {
            return Ok(());
        }
        match self.w.write_fmt(args).and_then(|()| self.w.flush()) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => {
                self.closed = true;
                Ok(())
            }
            Err(e) => Err(format!("standard output: {e}")),
        }
    }

    /// Writes `text` and a newline.
    pub fn line(&mut self, text: impl fmt::Display) -> Result<(), String> {
        self.write(format_args!("{text}\n"))
    }

    /// The writer.
    pub fn into_inner(self) -> W {
        self.w
    }
}

/// `outln!(out, "format", args…)`: a line on an [`Out`], `?` on its error.
#[macro_export]
macro_rules! outln {
    ($out:expr) => {
        $out.write(format_args!("\n"))?
    };
    ($out:expr, $($arg:tt)*) => {
        $out.write(format_args!("{}\n", format_args!($($arg)*)))?
    };
}

/// `out!(out, "format", args…)`: text on an [`Out`] without a newline, `?` on its error.
#[macro_export]
macro_rules! out {
    ($out:expr, $($arg:tt)*) => {
        $out.write(format_args!($($arg)*))?
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer whose reader has gone after `left` bytes.
    struct Pipe {
        left: usize,
        got: Vec<u8>,
    }

    impl Write for Pipe {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            if self.left == 0 {
                return Err(io::ErrorKind::BrokenPipe.into());
            }
            let n = b.len().min(self.left);
            self.left -= n;
            self.got.extend_from_slice(&b[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_closed_pipe_stops_the_output_quietly() {
        let mut out = Out::new(Pipe {
            left: 10,
            got: Vec::new(),
        });
        let mut written = 0;
        let run = |out: &mut Out<Pipe>, written: &mut usize| -> Result<(), String> {
            for i in 0..100 {
                outln!(out, "line {i}");
                if out.closed() {
                    break;
                }
                *written += 1;
            }
            Ok(())
        };
        assert_eq!(run(&mut out, &mut written), Ok(()));
        assert!(out.closed());
        assert!(written < 3, "{written}");
        assert_eq!(out.into_inner().got, b"line 0\nlin");
    }

    #[test]
    fn other_write_errors_are_errors() {
        struct Full;
        impl Write for Full {
            fn write(&mut self, _: &[u8]) -> io::Result<usize> {
                Err(io::Error::other("disk full"))
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let mut out = Out::new(Full);
        assert!(out.line("x").unwrap_err().contains("disk full"));
        assert!(!out.closed());
    }
}
