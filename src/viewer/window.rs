//! The window: an X11 software framebuffer (`minifb`, which loads Xlib at
//! run time, so building needs no X libraries), its keys and mouse read as
//! the viewer's [`Input`].

use anyhow::{anyhow, Context, Result};
use minifb::{MouseButton, MouseMode, ScaleMode, WindowOptions};

use super::walker::{Input, Key};

pub struct Window {
    inner: minifb::Window,
    /// Where the mouse was while the left button was down, last frame.
    dragging_from: Option<(f32, f32)>,
}

/// Shown in the title bar: what the keys do.
pub const KEYS: &str = "WASD/QE move, arrows or drag turn, shift faster, space play, \
                        comma/period scrub, home restart, F fill, T time, Esc quit";

impl Window {
    pub fn open(title: &str, width: u32, height: u32) -> Result<Window> {
        let options = WindowOptions {
            resize: true,
            scale_mode: ScaleMode::AspectRatioStretch,
            ..WindowOptions::default()
        };
        let mut inner = minifb::Window::new(title, width as usize, height as usize, options)
            .map_err(|e| anyhow!("{e}"))
            .with_context(|| {
                format!(
                    "opening a {width}x{height} window on X display `{}` (the viewer needs an X server, \
                     e.g. Xvfb, and Xlib: Debian's libx11-6 and libxcursor1)",
                    std::env::var("DISPLAY").unwrap_or_else(|_| "(DISPLAY is not set)".into())
                )
            })?;
        inner.set_target_fps(60);
        Ok(Window {
            inner,
            dragging_from: None,
        })
    }

    /// Open and not asked to close (the close button or Escape).
    pub fn is_open(&self) -> bool {
        self.inner.is_open() && !self.inner.is_key_down(minifb::Key::Escape)
    }

    /// The drawable size now, in pixels (at least 1 × 1).
    pub fn size(&self) -> (u32, u32) {
        let (w, h) = self.inner.get_size();
        (w.max(1) as u32, h.max(1) as u32)
    }

    /// The keys held and the mouse dragged since the last call.
    pub fn input(&mut self) -> Input {
        let keys = self.inner.get_keys().into_iter().filter_map(key).collect();
        let mouse = self.inner.get_mouse_pos(MouseMode::Pass);
        let drag = match (self.inner.get_mouse_down(MouseButton::Left), mouse) {
            (true, Some(now)) => {
                let from = self.dragging_from.replace(now).unwrap_or(now);
                (now.0 - from.0, now.1 - from.1)
            }
            _ => {
                self.dragging_from = None;
                (0.0, 0.0)
            }
        };
        Input { keys, drag }
    }

    /// Shows `width × height` pixels (`0RGB`), scaled to the window.
    pub fn show(&mut self, pixels: &[u32], width: u32, height: u32) -> Result<()> {
        self.inner
            .update_with_buffer(pixels, width as usize, height as usize)
            .map_err(|e| anyhow!("showing a {width}x{height} frame: {e}"))
    }

    /// Answers the window system without drawing anything new.
    pub fn pump(&mut self) {
        self.inner.update();
    }
}

fn key(k: minifb::Key) -> Option<Key> {
    use minifb::Key as M;
    Some(match k {
        M::W => Key::W,
        M::S => Key::S,
        M::A => Key::A,
        M::D => Key::D,
        M::E => Key::E,
        M::Q => Key::Q,
        M::Left => Key::Left,
        M::Right => Key::Right,
        M::Up => Key::Up,
        M::Down => Key::Down,
        M::Space => Key::Space,
        M::Comma => Key::Comma,
        M::Period => Key::Period,
        M::Home => Key::Home,
        M::F => Key::F,
        M::T => Key::T,
        M::LeftShift | M::RightShift => Key::Shift,
        _ => return None,
    })
}
