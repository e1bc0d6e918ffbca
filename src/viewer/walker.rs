//! The viewer's state between frames: where it stands and looks, the scene
//! time, and how frames are made; keys held over a time step change it.
//! The position never leaves the view space, since the bases saw too
//! little beyond it: a move across the edge ends on the edge.

use std::collections::BTreeSet;

use anyhow::{bail, Result};
use glam::{Quat, Vec3};

use crate::camera::Camera;
use crate::scene::{Animation, CameraDesc, ViewSpace};
use crate::synth::{Fill, TimeInterp};

/// The keys the viewer answers, named as scripts name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Key {
    /// Forward (W), back (S), left (A), right (D), up (E), down (Q).
    W,
    S,
    A,
    D,
    E,
    Q,
    /// Turn left and right, look up and down (arrows).
    Left,
    Right,
    Up,
    Down,
    /// Play or pause time.
    Space,
    /// Scrub time back and forward while held.
    Comma,
    Period,
    /// Back to the animation's start.
    Home,
    /// Next fill mode, next time interpolation.
    F,
    T,
    /// Move or turn ten times as fast while held.
    Shift,
}

impl Key {
    pub const ALL: [Key; 17] = [
        Key::W,
        Key::S,
        Key::A,
        Key::D,
        Key::E,
        Key::Q,
        Key::Left,
        Key::Right,
        Key::Up,
        Key::Down,
        Key::Space,
        Key::Comma,
        Key::Period,
        Key::Home,
        Key::F,
        Key::T,
        Key::Shift,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Key::W => "w",
            Key::S => "s",
            Key::A => "a",
            Key::D => "d",
            Key::E => "e",
            Key::Q => "q",
            Key::Left => "left",
            Key::Right => "right",
            Key::Up => "up",
            Key::Down => "down",
            Key::Space => "space",
            Key::Comma => "comma",
            Key::Period => "period",
            Key::Home => "home",
            Key::F => "f",
            Key::T => "t",
            Key::Shift => "shift",
        }
    }

    pub fn parse(name: &str) -> Result<Key> {
        match Key::ALL.iter().find(|k| k.name() == name) {
            Some(&k) => Ok(k),
            None => {
                let names: BTreeSet<&str> = Key::ALL.iter().map(|k| k.name()).collect();
                bail!(
                    "no key named `{name}` (keys: {})",
                    names.into_iter().collect::<Vec<_>>().join(", ")
                )
            }
        }
    }
}

/// What the user does during one time step: the keys held and how far the
/// mouse was dragged (pixels, right and down).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Input {
    pub keys: BTreeSet<Key>,
    pub drag: (f32, f32),
}

/// Turning rate of the arrow keys, radians per second.
const TURN_RATE: f32 = 1.2;
/// Turning per pixel of mouse drag, radians.
const DRAG_RATE: f32 = 0.005;
/// Nearest the view direction comes to straight up or down, radians.
const PITCH_MARGIN: f32 = 0.05;

/// Position, direction and time of the viewer, and its synthesis modes.
#[derive(Clone, Debug, PartialEq)]
pub struct Walker {
    pub position: Vec3,
    /// Unit view direction.
    pub direction: Vec3,
    /// The world's up: turning is about it, and moves up and down go along it.
    pub up: Vec3,
    pub vfov_deg: f32,
    pub time: f32,
    pub playing: bool,
    pub fill: Fill,
    pub time_interp: TimeInterp,
    /// Whether the last step's move was stopped at the view space's edge.
    pub at_edge: bool,
    /// Scene units per second.
    pub speed: f32,
    space: Option<ViewSpace>,
    animation: Animation,
    held: BTreeSet<Key>,
}

impl Walker {
    /// A viewer at `start`'s pose (moved into the view space) at `time`.
    pub fn new(
        start: &CameraDesc,
        time: f32,
        space: Option<ViewSpace>,
        animation: Animation,
        speed: f32,
        fill: Fill,
        time_interp: TimeInterp,
    ) -> Result<Walker> {
        if !(speed.is_finite() && speed > 0.0) {
            bail!("speed {speed} must be a positive number of scene units per second");
        }
        if !time.is_finite() {
            bail!("start time {time} is not a number");
        }
        let up = start.up.normalize_or_zero();
        if up == Vec3::ZERO || up.cross(start.direction).length_squared() < 1e-12 {
            bail!(
                "camera `{}`: up {} and direction {} do not make a frame",
                start.name,
                start.up,
                start.direction
            );
        }
        let mut w = Walker {
            position: start.position,
            direction: start.direction.normalize(),
            up,
            vfov_deg: start.vfov_deg,
            time,
            playing: animation.end > animation.start,
            fill,
            time_interp,
            at_edge: false,
            speed,
            space,
            animation,
            held: BTreeSet::new(),
        };
        w.position = w.clamp(start.position);
        w.direction = w.turn(w.direction, 0.0, 0.0);
        Ok(w)
    }

    /// The perspective camera of the viewer's pose at `width × height`.
    pub fn camera(&self, width: u32, height: u32) -> Result<Camera> {
        self.desc().perspective(width, height)
    }

    pub fn desc(&self) -> CameraDesc {
        CameraDesc {
            name: "viewer".into(),
            position: self.position,
            direction: self.direction,
            up: self.up,
            vfov_deg: self.vfov_deg,
        }
    }

    /// Takes a path's pose: its position is the path's, inside the view
    /// space or not, as `rangewalk walk` shows it.
    pub fn follow(&mut self, pose: &CameraDesc, time: f32) {
        self.position = pose.position;
        self.direction = pose.direction.normalize_or_zero();
        self.up = pose.up;
        self.vfov_deg = pose.vfov_deg;
        self.time = time;
        self.at_edge = false;
    }

    /// One time step of `dt` seconds with `input` held: keys pressed since
    /// the last step toggle, held keys move, turn and scrub.
    pub fn step(&mut self, input: &Input, dt: f32) {
        let pressed: Vec<Key> = input.keys.difference(&self.held).copied().collect();
        self.held = input.keys.clone();
        let down = |k: Key| input.keys.contains(&k);
        for k in pressed {
            match k {
                Key::Space => self.playing = !self.playing,
                Key::Home => self.time = self.animation.start,
                Key::F => self.fill = next_fill(self.fill),
                Key::T => self.time_interp = next_interp(self.time_interp),
                _ => {}
            }
        }
        let boost = if down(Key::Shift) { 10.0 } else { 1.0 };
        let axis = |plus: Key, minus: Key| (down(plus) as i32 - down(minus) as i32) as f32;
        // Turning: yaw about the world's up, pitch about the right.
        let yaw = -axis(Key::Right, Key::Left) * TURN_RATE * boost * dt - input.drag.0 * DRAG_RATE;
        let pitch = axis(Key::Up, Key::Down) * TURN_RATE * boost * dt - input.drag.1 * DRAG_RATE;
        if yaw != 0.0 || pitch != 0.0 {
            self.direction = self.turn(self.direction, yaw, pitch);
        }
        // Moving: forward along the ground, not into it.
        let ahead = (self.direction - self.up * self.direction.dot(self.up)).normalize_or_zero();
        let right = ahead.cross(self.up);
        let step = ahead * axis(Key::W, Key::S)
            + right * axis(Key::D, Key::A)
            + self.up * axis(Key::E, Key::Q);
        if step != Vec3::ZERO {
            let wanted = self.position + step.normalize() * self.speed * boost * dt;
            self.position = self.clamp(wanted);
            self.at_edge = self.position.distance(wanted) > 1e-6 * self.speed.max(1e-30);
        } else {
            self.at_edge = false;
        }
        // Time: plays looping, scrubs at real speed within the animation.
        let (start, end) = (self.animation.start, self.animation.end);
        if end > start {
            let scrub = axis(Key::Period, Key::Comma);
            if scrub != 0.0 {
                self.time = (self.time + scrub * boost * dt).clamp(start, end);
            } else if self.playing {
                let t = self.time + dt;
                self.time = if t > end {
                    start + (t - start) % (end - start)
                } else {
                    t
                };
            }
        }
    }

    /// The point of the view space nearest `p` (`p` itself without one).
    pub fn clamp(&self, p: Vec3) -> Vec3 {
        self.space.map_or(p, |s| s.clamp(p))
    }

    /// `d` turned by `yaw` about the world's up and raised by `pitch`, its
    /// elevation kept [`PITCH_MARGIN`] short of straight up or down, where
    /// turning about the up would spin the view.
    fn turn(&self, d: Vec3, yaw: f32, pitch: f32) -> Vec3 {
        let max = std::f32::consts::FRAC_PI_2 - PITCH_MARGIN;
        let h = d.dot(self.up).clamp(-1.0, 1.0);
        let elevation = (h.asin() + pitch).clamp(-max, max);
        let flat = (d - self.up * h).normalize_or_zero();
        let flat = if flat == Vec3::ZERO {
            self.up.any_orthonormal_vector()
        } else {
            flat
        };
        let flat = Quat::from_axis_angle(self.up, yaw) * flat;
        (flat * elevation.cos() + self.up * elevation.sin()).normalize()
    }
}

fn next_fill(f: Fill) -> Fill {
    match f {
        Fill::None => Fill::Foreground,
        Fill::Foreground => Fill::Background,
        Fill::Background => Fill::Both,
        Fill::Both => Fill::None,
    }
}

fn next_interp(t: TimeInterp) -> TimeInterp {
    match t {
        TimeInterp::Linear => TimeInterp::Motion,
        TimeInterp::Motion => TimeInterp::Reshade,
        TimeInterp::Reshade => TimeInterp::Linear,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walker(space: Option<ViewSpace>) -> Walker {
        let start = CameraDesc {
            name: "start".into(),
            position: Vec3::new(0.0, 1.0, 0.0),
            direction: Vec3::Z,
            up: Vec3::Y,
            vfov_deg: 40.0,
        };
        let animation = Animation {
            start: 0.0,
            end: 1.0,
            fps: 30.0,
        };
        Walker::new(
            &start,
            0.0,
            space,
            animation,
            1.0,
            Fill::Both,
            TimeInterp::Motion,
        )
        .unwrap()
    }

    fn hold(keys: &[Key]) -> Input {
        Input {
            keys: keys.iter().copied().collect(),
            drag: (0.0, 0.0),
        }
    }

    #[test]
    fn forward_moves_along_the_view_and_stops_at_the_box() {
        let space = ViewSpace::Box {
            min: Vec3::new(-1.0, 0.0, -1.0),
            max: Vec3::new(1.0, 2.0, 0.5),
        };
        let mut w = walker(Some(space));
        w.step(&hold(&[Key::W]), 0.25);
        assert!((w.position - Vec3::new(0.0, 1.0, 0.25)).length() < 1e-6);
        assert!(!w.at_edge);
        w.step(&hold(&[Key::W]), 1.0);
        assert!((w.position - Vec3::new(0.0, 1.0, 0.5)).length() < 1e-6);
        assert!(w.at_edge, "a move past the edge is reported");
        w.step(&hold(&[Key::S]), 0.5);
        assert!((w.position - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
        assert!(!w.at_edge);
    }

    #[test]
    fn a_segment_keeps_only_the_move_along_it() {
        let space = ViewSpace::Segment {
            a: Vec3::new(-1.0, 1.0, 0.0),
            b: Vec3::new(1.0, 1.0, 0.0),
        };
        let mut w = walker(Some(space));
        // Right and forward at once: half of the unit step is along x.
        w.step(&hold(&[Key::D, Key::W]), 1.0);
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((w.position - Vec3::new(-s, 1.0, 0.0)).length() < 1e-5);
        w.step(&hold(&[Key::A]), 5.0);
        assert!((w.position - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
        assert!(w.at_edge);
    }

    #[test]
    fn turning_keeps_the_horizon_and_never_reaches_the_pole() {
        let mut w = walker(None);
        w.step(&hold(&[Key::Left]), std::f32::consts::FRAC_PI_2 / TURN_RATE);
        assert!((w.direction - Vec3::X).length() < 1e-5, "{}", w.direction);
        for _ in 0..100 {
            w.step(&hold(&[Key::Up]), 0.1);
        }
        let top = (std::f32::consts::FRAC_PI_2 - PITCH_MARGIN).sin();
        assert!((w.direction.dot(Vec3::Y) - top).abs() < 1e-5);
        w.step(&hold(&[Key::Down]), 100.0);
        assert!(
            (w.direction.dot(Vec3::Y) + top).abs() < 1e-5,
            "one long step stops too"
        );
        assert!(w.camera(8, 8).is_ok());
    }

    #[test]
    fn toggles_fire_once_per_press_and_time_loops() {
        let mut w = walker(None);
        assert!(w.playing);
        w.step(&hold(&[Key::Space]), 0.1);
        w.step(&hold(&[Key::Space]), 0.1);
        assert!(!w.playing, "holding space toggles once");
        assert_eq!(w.time, 0.0);
        w.step(&hold(&[]), 0.1);
        w.step(&hold(&[Key::Space, Key::F]), 0.5);
        assert!(w.playing);
        assert_eq!(w.fill, Fill::None);
        w.step(&hold(&[]), 0.75);
        assert!((w.time - 0.25).abs() < 1e-5, "{}", w.time);
        w.step(&hold(&[Key::Comma]), 2.0);
        assert_eq!(w.time, 0.0, "scrubbing stops at the start");
    }

    #[test]
    fn key_names_parse_back() {
        for k in Key::ALL {
            assert_eq!(Key::parse(k.name()).unwrap(), k);
        }
        let e = Key::parse("jump").unwrap_err().to_string();
        assert!(e.contains("`jump`") && e.contains("space"), "{e}");
    }
}
