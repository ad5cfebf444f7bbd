//! The command's error type: a message saying what was being done, and the error
//! that stopped it.
//!
//! A small stand-in for `anyhow`, so the workspace needs no extra dependency:
//! [`Context::with_context`] wraps any error with a sentence, and `main` prints the
//! whole chain (`cannot read mesh foo.obj: No such file or directory`).

use std::fmt;

/// A failure with a human-readable description and an optional cause.
#[derive(Debug)]
pub struct Error {
    message: String,
    source: Option<Box<dyn std::error::Error + Send + Sync + 'static>>,
}

/// Result with the command's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An error with no underlying cause.
    pub fn msg(message: impl Into<String>) -> Self {
        Error {
            message: message.into(),
            source: None,
        }
    }

    /// The message followed by every cause, separated by `: `.
    pub fn chain(&self) -> String {
        let mut text = self.message.clone();
        let mut cause = std::error::Error::source(self);
        while let Some(error) = cause {
            text.push_str(": ");
            text.push_str(&error.to_string());
            cause = error.source();
        }
        text
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source
            .as_deref()
            .map(|error| error as &(dyn std::error::Error + 'static))
    }
}

/// Adds a description of what was being done to a failing result.
pub trait Context<T> {
    /// Wraps the error with a message built only when there is an error.
    fn with_context<M: Into<String>>(self, message: impl FnOnce() -> M) -> Result<T>;
}

impl<T, E> Context<T> for std::result::Result<T, E>
where
    E: std::error::Error + Send + Sync + 'static,
{
    fn with_context<M: Into<String>>(self, message: impl FnOnce() -> M) -> Result<T> {
        self.map_err(|error| Error {
            message: message().into(),
            source: Some(Box::new(error)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chain_lists_message_then_causes() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let error = Err::<(), _>(io)
            .with_context(|| "cannot read mesh a.obj")
            .unwrap_err();
        assert_eq!(error.chain(), "cannot read mesh a.obj: no such file");
        let outer = Err::<(), _>(error)
            .with_context(|| "render failed")
            .unwrap_err();
        assert_eq!(
            outer.chain(),
            "render failed: cannot read mesh a.obj: no such file"
        );
    }
}
