//! The interactive walk-through (`rangewalk view`): a window that shows
//! frames synthesized from a bake while the viewer moves and time plays,
//! the paper's "real time walk-through". Frames come from
//! [`crate::synth::Synthesizer`] unchanged, on a thread of their own; this
//! module holds only the window, the input and what is drawn over frames.

pub mod command;
pub mod overlay;
mod render;
pub mod script;
pub mod walker;
mod window;
