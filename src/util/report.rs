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

/// The longest line an error quotes whole, in bytes; a longer one keeps its head and tail ([`capped`]).
pub const MAX_QUOTED_LINE: usize = 1000;

/// The most lines an error prints; the rest are counted ([`capped`]).
pub const MAX_QUOTED_LINES: usize = 24;

/// `text` with each line longer than [`MAX_QUOTED_LINE`] bytes cut to its first 700 and last 200 (at character
/// boundaries) around "… [N bytes left out] …", and at most [`MAX_QUOTED_LINES`] lines, so that an error quoting
/// its input (toml's snippet of the offending line, a file name) stays readable however large the input: a
/// 10⁶-element array or an 8 MiB string in a scene printed 4–8 MB on stderr.
pub fn capped(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(MAX_QUOTED_LINE * MAX_QUOTED_LINES));
    let lines = text.split('\n').count();
    for (i, line) in text.split('\n').enumerate() {
        if i == MAX_QUOTED_LINES {
            out.push_str(&format!("\n… [{} more lines]", lines - i));
            break;
        }
        if i > 0 {
            out.push('\n');
        }
        if line.len() <= MAX_QUOTED_LINE {
            out.push_str(line);
            continue;
        }
        let head = floor_boundary(line, 700);
        let tail = ceil_boundary(line, line.len() - 200);
        out.push_str(&line[..head]);
        out.push_str(&format!("… [{} bytes left out] …", tail - head));
        out.push_str(&line[tail..]);
    }
    out
}

/// The largest character boundary of `s` at or below `i`.
fn floor_boundary(s: &str, mut i: usize) -> usize {
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// The smallest character boundary of `s` at or above `i`.
fn ceil_boundary(s: &str, mut i: usize) -> usize {
    while !s.is_char_boundary(i) {
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_lines_and_many_lines_are_cut_with_what_was_left_out_counted() {
        let long = format!("key = \"{}\"", "é".repeat(1 << 20));
        let c = capped(&format!("line 1\n{long}\nlast"));
        assert!(c.len() < 2000, "{}", c.len());
        assert!(c.starts_with("line 1\nkey = \"éé"), "{c}");
        assert!(c.ends_with("é\"\nlast"), "{c}");
        assert!(c.contains("bytes left out"), "{c}");
        let many: String = (0..100).map(|i| format!("{i}\n")).collect();
        let c = capped(&many);
        assert_eq!(c.lines().count(), MAX_QUOTED_LINES + 1);
        assert!(c.ends_with("[77 more lines]"), "{c}");
        assert_eq!(capped("short\nlines"), "short\nlines");
    }

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
