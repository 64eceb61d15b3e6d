//! Frames stream to disk as the bake makes them: every export is a [`FrameSink`] that takes
//! each frame once, in order, and holds no more than one frame (plus what its format needs to
//! close the file). Memory stays flat however long the shot: the frames live in the files.
//!
//! A bake hands every sink the same [`Frame`]s: the positions of every mesh it shows (garments,
//! then characters, then colliders, described once by [`MeshInfo`]), and tells them when a
//! mesh's faces change (tearing). [`Sinks`] drives a set of them and times each;
//! [`Threaded`] runs a sink on its own thread while the GPU simulates.

use crate::error::Result;
use crate::report::ExportReport;
use glam::Vec3;
use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, SyncSender};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What a mesh is in the bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Garment,
    Character,
    Collider,
}

/// A mesh as every sink knows it before the first frame.
#[derive(Clone, Debug)]
pub struct MeshInfo {
    pub name: String,
    pub role: Role,
    /// Faces at the first frame; empty for a rope (a polyline).
    pub triangles: Vec<[u32; 3]>,
    /// Texture coordinates per vertex, if any.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Base colour, linear RGBA.
    pub colour: [f32; 4],
    /// Vertices (every frame has this many).
    pub vertices: usize,
    /// False for a mesh that never moves (a static collider or character): it comes with the
    /// first frame only.
    pub animated: bool,
}

/// One baked frame of every mesh.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Index among the baked frames (0 for the first).
    pub index: usize,
    /// The shot's frame number (`frame_start + index`).
    pub number: u32,
    /// Positions of every mesh, in [`MeshInfo`] order; a static mesh's are empty after the
    /// first frame.
    pub positions: Vec<Vec<Vec3>>,
}

/// What a sink wrote, for the report.
#[derive(Clone, Debug)]
pub struct Written {
    /// The report's name of the format (`"gltf"`, `"pc2"`, …).
    pub format: &'static str,
    pub files: Vec<PathBuf>,
    /// What the user should know (a container that could not hold the bake, …).
    pub warnings: Vec<String>,
}

/// An export that takes frames as they are baked.
pub trait FrameSink: Send {
    /// Takes the next frame.
    fn frame(&mut self, frame: &Frame) -> Result<()>;
    /// From frame index `from` on, mesh `mesh` has these faces (it tore).
    fn faces(&mut self, mesh: usize, from: usize, triangles: &[[u32; 3]]) -> Result<()>;
    /// Closes the files after `frames` frames.
    fn finish(self: Box<Self>, frames: usize) -> Result<Vec<Written>>;
}

/// Total size of `files` [bytes].
fn size_of(files: &[PathBuf]) -> u64 {
    files
        .iter()
        .filter_map(|f| std::fs::metadata(f).ok())
        .map(|m| m.len())
        .sum()
}

/// A set of sinks driven together, each timed (the report's per-format milliseconds).
#[derive(Default)]
pub struct Sinks {
    sinks: Vec<(Box<dyn FrameSink>, Duration)>,
}

impl Sinks {
    pub fn push(&mut self, sink: Box<dyn FrameSink>) {
        self.sinks.push((sink, Duration::ZERO));
    }

    pub fn is_empty(&self) -> bool {
        self.sinks.is_empty()
    }

    /// Closes every sink and reports what each wrote (its time, every frame and the close, goes
    /// to the first format it names).
    pub fn close(self, frames: usize) -> Result<(Vec<ExportReport>, Vec<Written>)> {
        let mut reports = Vec::new();
        let mut all = Vec::new();
        for (sink, spent) in self.sinks {
            let start = Instant::now();
            let written = sink.finish(frames)?;
            let mut ms = (spent + start.elapsed()).as_secs_f64() * 1e3;
            for w in written {
                reports.push(ExportReport {
                    format: w.format,
                    files: w.files.len(),
                    bytes: size_of(&w.files),
                    ms: std::mem::take(&mut ms),
                });
                all.push(w);
            }
        }
        Ok((reports, all))
    }
}

impl FrameSink for Sinks {
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        for (sink, spent) in &mut self.sinks {
            let start = Instant::now();
            sink.frame(frame)?;
            *spent += start.elapsed();
        }
        Ok(())
    }

    fn faces(&mut self, mesh: usize, from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        for (sink, _) in &mut self.sinks {
            sink.faces(mesh, from, triangles)?;
        }
        Ok(())
    }

    fn finish(self: Box<Self>, frames: usize) -> Result<Vec<Written>> {
        Ok(self.close(frames)?.1)
    }
}

/// What the bake hands a sink's thread, in order.
enum Message {
    Frame(Frame),
    Faces(usize, usize, Vec<[u32; 3]>),
}

/// A sink on its own thread: the bake hands over each frame (through a channel of two) and
/// only waits when the writer falls two frames behind. That pays while the GPU simulates and
/// the CPU waits; when the CPU solver keeps every core busy a writer thread only takes turns
/// with it (scene H on 2 cores: 9.9 → 19 ms per simulated frame), so there sinks run in line.
/// The first error stops the thread and is returned by the next call.
pub struct Threaded {
    send: Option<SyncSender<Message>>,
    thread: Option<JoinHandle<Result<Sinks>>>,
}

impl Threaded {
    pub fn spawn(mut sinks: Sinks) -> Threaded {
        let (send, receive) = sync_channel::<Message>(2);
        let thread = std::thread::spawn(move || {
            for message in receive {
                match message {
                    Message::Frame(f) => sinks.frame(&f)?,
                    Message::Faces(mesh, from, t) => sinks.faces(mesh, from, &t)?,
                }
            }
            Ok(sinks)
        });
        Threaded {
            send: Some(send),
            thread: Some(thread),
        }
    }

    /// Hands `message` over; if the thread stopped, returns its error.
    fn send(&mut self, message: Message) -> Result<()> {
        let sent = self.send.as_ref().is_some_and(|s| s.send(message).is_ok());
        if sent {
            return Ok(());
        }
        self.join().map(|_| ())
    }

    /// Waits for every queued frame and returns the sinks.
    fn join(&mut self) -> Result<Sinks> {
        self.send = None;
        match self.thread.take() {
            Some(t) => t.join().expect("a frame sink does not panic"),
            None => Ok(Sinks::default()),
        }
    }

    /// Waits for every queued frame, then closes the sinks.
    pub fn close(mut self, frames: usize) -> Result<(Vec<ExportReport>, Vec<Written>)> {
        self.join()?.close(frames)
    }

    pub fn frame(&mut self, frame: Frame) -> Result<()> {
        self.send(Message::Frame(frame))
    }

    pub fn faces(&mut self, mesh: usize, from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        self.send(Message::Faces(mesh, from, triangles.to_vec()))
    }
}

impl Drop for Threaded {
    fn drop(&mut self) {
        let _ = self.join();
    }
}

/// The bake's sinks, in line (CPU backend) or on their own thread (GPU backend).
pub enum Output {
    Inline(Sinks),
    Threaded(Threaded),
}

impl Output {
    pub fn new(sinks: Sinks, on_a_thread: bool) -> Output {
        if on_a_thread && !sinks.is_empty() {
            Output::Threaded(Threaded::spawn(sinks))
        } else {
            Output::Inline(sinks)
        }
    }

    pub fn frame(&mut self, frame: Frame) -> Result<()> {
        match self {
            Output::Inline(s) => s.frame(&frame),
            Output::Threaded(t) => t.frame(frame),
        }
    }

    pub fn faces(&mut self, mesh: usize, from: usize, triangles: &[[u32; 3]]) -> Result<()> {
        match self {
            Output::Inline(s) => s.faces(mesh, from, triangles),
            Output::Threaded(t) => t.faces(mesh, from, triangles),
        }
    }

    pub fn close(self, frames: usize) -> Result<(Vec<ExportReport>, Vec<Written>)> {
        match self {
            Output::Inline(s) => s.close(frames),
            Output::Threaded(t) => t.close(frames),
        }
    }
}
