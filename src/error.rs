//! One error type for the whole program. The variant decides the exit code, the text is
//! the one line the user sees (it names the file, the place and the fix).

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Bad input (case file, mesh, command line): exit code 2.
    Input(String),
    /// The numbers went wrong (NaN, divergence, a singular matrix): exit code 4.
    Numerical(String),
    /// Writing outputs failed: exit code 5.
    Output(String),
    /// Another rank failed and reported it; this rank exits with that code quietly.
    Silent(i32),
}

impl Error {
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input(_) => 2,
            Error::Numerical(_) => 4,
            Error::Output(_) => 5,
            Error::Silent(code) => *code,
        }
    }

    pub fn message(&self) -> &str {
        match self {
            Error::Input(m) | Error::Numerical(m) | Error::Output(m) => m,
            Error::Silent(_) => "",
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;

/// Shorthand for an input error.
pub fn input<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Input(msg.into()))
}
