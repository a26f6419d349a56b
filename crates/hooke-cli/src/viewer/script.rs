//! Scripted input for `hooke view --script drag`: synthetic mouse and panel events fed through
//! the viewer's own handlers, so a test (or a demo) exercises exactly what a user's hand does.
//! The drag script presses on the cloth, drags the grabbed vertex for [`DRAG_MOVES`] frames,
//! changes the stiffness, the damping and dt one after another, and releases.

use clap::ValueEnum;
use glam::Vec2;

/// Frames of cursor motion while the cloth is held.
pub const DRAG_MOVES: u32 = 30;
/// Cursor motion per frame, pixels.
const STEP: Vec2 = Vec2::new(4.0, -3.0);

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Script {
    /// Press on the cloth, drag it for 30 frames, change stiffness, damping and dt, release.
    Drag,
}

/// What the script does next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Put the cursor on this pixel and press the left button.
    Press(Vec2),
    /// Move the cursor by this many pixels.
    Move(Vec2),
    /// Change the stiffness, damping and dt, as three panel edits.
    Tune,
    Release,
    Nothing,
}

/// Progress through the drag script.
#[derive(Debug, Default)]
pub struct DragScript {
    pressed: bool,
    moves: u32,
    tuned: bool,
    released: bool,
    /// The vertex the press grabbed.
    pub grabbed: Option<u32>,
}

impl DragScript {
    /// The next action, given the frame number and the vertex held now (if any). `target` is
    /// the pixel where the cloth's middle vertex appears.
    pub fn next(&mut self, frame: u64, holding: Option<u32>, target: Vec2) -> Action {
        if frame < 2 || self.released {
            return Action::Nothing;
        }
        if !self.pressed {
            self.pressed = true;
            return Action::Press(target);
        }
        if self.grabbed.is_none() {
            // The pick answers a few frames after the press, without waiting.
            self.grabbed = holding;
            if holding.is_none() {
                return Action::Nothing;
            }
        }
        if self.moves < DRAG_MOVES {
            self.moves += 1;
            return Action::Move(STEP);
        }
        if !self.tuned {
            self.tuned = true;
            return Action::Tune;
        }
        self.released = true;
        Action::Release
    }

    /// One line for the end of the run.
    pub fn report(&self) -> String {
        match self.grabbed {
            Some(vertex) => format!(
                "scripted drag: grabbed vertex {vertex}, {} moves, stiffness, damping and dt changed: {}, released: {}",
                self.moves, self.tuned, self.released
            ),
            None => "scripted drag: no vertex was grabbed".to_owned(),
        }
    }
}
