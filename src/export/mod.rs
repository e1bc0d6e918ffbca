//! Scene export to other renderers, for validation.
