//! Frames made on a thread of their own, so that the window keeps
//! answering while a frame (or the first reading of the bases) takes long.
//! One request is in flight at a time: the window asks for the newest pose
//! only when the last frame has come back, so it never waits on stale ones.

use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{anyhow, Context, Result};

use crate::bake::Bake;
use crate::camera::Camera;
use crate::image;
use crate::scene::Scene;
use crate::synth::{FrameStats, Options, Synthesizer};

/// A frame to make.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    pub camera: Camera,
    pub time: f32,
    pub options: Options,
}

/// A frame made: tone-mapped 8-bit sRGB, as `rangewalk synth --preview`
/// writes it.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub request: Request,
    pub rgb: Vec<u8>,
    pub stats: FrameStats,
    /// Base views the frame's images belong to, without repeats.
    pub views: Vec<usize>,
}

pub struct Renderer {
    requests: Option<Sender<Request>>,
    frames: Receiver<Result<Rendered>>,
    thread: Option<JoinHandle<()>>,
    busy: bool,
}

impl Renderer {
    /// Starts the thread, which owns the scene, the bake and the bases it
    /// has read (at most `budget` bytes).
    pub fn start(scene: Arc<Scene>, bake: Bake, budget: usize, exposure: f32) -> Result<Renderer> {
        let (requests, inbox) = mpsc::channel::<Request>();
        let (outbox, frames) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("synthesis".into())
            .spawn(move || {
                let mut synth = Synthesizer::new(&scene, &bake, budget);
                for request in inbox {
                    let made = synth
                        .frame(&request.camera, request.time, &request.options)
                        .map(|(frame, stats)| {
                            let mut views: Vec<usize> = stats
                                .images
                                .iter()
                                .map(|&k| bake.manifest.images[k].view)
                                .collect();
                            views.sort_unstable();
                            views.dedup();
                            let rgb = image::tonemap_srgb8(&frame.radiance, exposure);
                            synth.recycle(frame);
                            Rendered {
                                rgb,
                                request,
                                stats,
                                views,
                            }
                        });
                    if outbox.send(made).is_err() {
                        break;
                    }
                }
            })
            .context("starting the synthesis thread")?;
        Ok(Renderer {
            requests: Some(requests),
            frames,
            thread: Some(thread),
            busy: false,
        })
    }

    /// Whether a frame is being made.
    pub fn busy(&self) -> bool {
        self.busy
    }

    /// Asks for a frame; call only when not [`busy`](Self::busy).
    pub fn request(&mut self, request: Request) -> Result<()> {
        debug_assert!(!self.busy, "one request at a time");
        self.requests
            .as_ref()
            .expect("the sender lives until drop")
            .send(request)
            .map_err(|_| self.stopped())?;
        self.busy = true;
        Ok(())
    }

    /// The frame asked for, if it comes within `wait`.
    pub fn poll(&mut self, wait: Duration) -> Result<Option<Rendered>> {
        if !self.busy {
            return Ok(None);
        }
        match self.frames.recv_timeout(wait) {
            Ok(made) => {
                self.busy = false;
                made.map(Some)
            }
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(self.stopped()),
        }
    }

    /// Why the thread is gone: its panic's message where it panicked.
    fn stopped(&mut self) -> anyhow::Error {
        let why = match self.thread.take().map(JoinHandle::join) {
            Some(Err(panic)) => panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "a panic".into()),
            _ => "it ended".into(),
        };
        anyhow!("the synthesis thread stopped: {why}")
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        // Closing the channel ends the thread's loop after its frame.
        self.requests = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
