//! How a bake shows its progress: a bar on a terminal (`drape bake`), nothing (library callers,
//! tests), or a line per frame on stderr for a caller that draws its own progress (the Blender
//! add-on runs `drape bake --progress-lines`).

use std::cell::Cell;

/// Where a bake's progress goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProgressView {
    Hidden,
    /// A bar on stderr (drawn only when stderr is a terminal).
    Bar,
    /// `drape: K of N frames` on stderr after each frame.
    Lines,
}

/// Counts the frames a bake has made and shows them as its [`ProgressView`] says.
pub struct Ticker {
    bar: indicatif::ProgressBar,
    /// Lines mode: the frames done and the frames asked for.
    lines: Option<(Cell<u64>, u64)>,
}

impl Ticker {
    pub fn new(frames: u64, view: ProgressView) -> Ticker {
        let bar = match view {
            ProgressView::Bar => {
                let bar = indicatif::ProgressBar::with_draw_target(
                    Some(frames),
                    indicatif::ProgressDrawTarget::stderr(),
                );
                if let Ok(style) = indicatif::ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} frames {elapsed} (eta {eta})",
                ) {
                    bar.set_style(style);
                }
                bar
            }
            _ => indicatif::ProgressBar::hidden(),
        };
        Ticker {
            bar,
            lines: (view == ProgressView::Lines).then(|| (Cell::new(0), frames)),
        }
    }

    /// `frames` more frames are done.
    pub fn inc(&self, frames: u64) {
        self.bar.inc(frames);
        if let Some((done, of)) = &self.lines {
            done.set(done.get() + frames);
            if frames > 0 {
                eprintln!("drape: {} of {of} frames", done.get());
            }
        }
    }

    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
