//! Progress bars on the terminal for the command line; in the C library
//! (built without the `cli` feature) the same calls draw nothing, so that
//! a host pipeline's stderr stays its own and indicatif is not linked.

#[cfg(feature = "cli")]
pub use indicatif::{ProgressBar, ProgressStyle};

#[cfg(not(feature = "cli"))]
pub use silent::{ProgressBar, ProgressStyle};

/// indicatif's calls that the library makes, doing nothing.
#[cfg(not(feature = "cli"))]
mod silent {
    use std::borrow::Cow;
    use std::convert::Infallible;

    pub struct ProgressBar;

    impl ProgressBar {
        pub fn new(_len: u64) -> Self {
            ProgressBar
        }

        pub fn new_spinner() -> Self {
            ProgressBar
        }

        pub fn with_style(self, _style: ProgressStyle) -> Self {
            self
        }

        pub fn inc(&self, _delta: u64) {}

        pub fn inc_length(&self, _delta: u64) {}

        pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
            f()
        }

        pub fn set_message(&self, _message: impl Into<Cow<'static, str>>) {}

        pub fn finish_and_clear(&self) {}
    }

    pub struct ProgressStyle;

    impl ProgressStyle {
        pub fn with_template(_template: &str) -> Result<Self, Infallible> {
            Ok(ProgressStyle)
        }
    }
}
