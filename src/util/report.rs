//! One line for an error and its causes, each said once.
//!
//! Why errors were printed twice: the library's error types show their cause in their own message
//! (`#[error("{path}: {source}")]`, so `to_string()` alone is complete for a test, a warning or a log line) *and*
//! return the same cause from [`Error::source`] (thiserror does so for any field named `source`). anyhow's
//! alternate form (`{:#}`) prints every link of that chain, so "No such file or directory (os error 2)" came out
//! twice. [`chain`] walks the same chain but leaves out a cause whose text the line already contains, so both
//! kinds of error type (cause in the message, or cause only in `source()`, as anyhow's `context` makes) print each
//! piece exactly once.

use std::error::Error;

/// `error`'s message followed by each cause not already part of it, joined by ": ".
pub fn chain(error: &(dyn Error + 'static)) -> String {
    let mut line = error.to_string();
    let mut cause = error.source();
    while let Some(e) = cause {
        let text = e.to_string();
        if !text.is_empty() && !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        cause = e.source();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("scene.toml: {source}")]
    struct Shows {
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("cannot read the scene")]
    struct Hides {
        #[source]
        source: std::io::Error,
    }

    #[test]
    fn each_cause_is_printed_once() {
        let io = || std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        assert_eq!(chain(&Shows { source: io() }), "scene.toml: no such file");
        assert_eq!(
            chain(&Hides { source: io() }),
            "cannot read the scene: no such file"
        );
    }
}
