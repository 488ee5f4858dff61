//! A chart with lines of text under it ([`WithNotes`]): the studies' equal-time and equal-error read-outs, drawn
//! into both the PNG and the SVG of the chart.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{text_style, Chart, DrawResult, INK, TICK_SIZE};

/// Height of one line of notes, pixels.
pub const NOTE_LINE: u32 = 20;

/// `chart` above `notes`, left-aligned in [`TICK_SIZE`] text, each note wrapped at word boundaries to
/// [`MAX_CHARS`] characters. The page must be [`WithNotes::extra_height`] taller than the chart alone.
#[derive(Debug, Clone, PartialEq)]
pub struct WithNotes<C> {
    /// The chart, drawn in the area above the notes.
    pub chart: C,
    /// The lines under it.
    pub notes: Vec<String>,
}

/// Characters per wrapped line (a conservative fit of DejaVu Sans at [`TICK_SIZE`] in a 960-pixel page).
pub const MAX_CHARS: usize = 118;

impl<C> WithNotes<C> {
    /// The notes wrapped at word boundaries to [`MAX_CHARS`] characters; continuation lines are indented.
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        for note in &self.notes {
            let mut line = String::new();
            for word in note.split(' ') {
                if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > MAX_CHARS {
                    out.push(std::mem::replace(&mut line, "    ".to_owned()));
                }
                if !line.trim().is_empty() {
                    line.push(' ');
                }
                line.push_str(word);
            }
            out.push(line);
        }
        out
    }

    /// The height the notes take, pixels.
    pub fn extra_height(&self) -> usize {
        if self.notes.is_empty() {
            0
        } else {
            (self.lines().len() as u32 * NOTE_LINE + 12) as usize
        }
    }
}

impl<C: Chart> Chart for WithNotes<C> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let (_, height) = root.dim_in_pixel();
        let split = height.saturating_sub(self.extra_height() as u32);
        let (top, bottom) = root.split_vertically(split);
        self.chart.draw(&top)?;
        let style = text_style(TICK_SIZE, INK).pos(Pos::new(HPos::Left, VPos::Top));
        for (i, line) in self.lines().iter().enumerate() {
            bottom.draw_text(
                line.as_str(),
                &style,
                (16, 4 + (i as u32 * NOTE_LINE) as i32),
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_wrap_at_words() {
        let long = ["word"; 40].join(" ");
        let n = WithNotes {
            chart: (),
            notes: vec!["short".into(), long],
        };
        let lines = n.lines();
        assert_eq!(lines[0], "short");
        assert!(
            lines.len() == 3 && lines.iter().all(|l| l.chars().count() <= MAX_CHARS),
            "{lines:?}"
        );
        assert!(lines[2].starts_with("    word"));
        assert_eq!(n.extra_height(), 3 * NOTE_LINE as usize + 12);
    }
}
