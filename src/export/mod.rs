//! Scene export to other renderers, for validation.

pub mod mitsuba;
