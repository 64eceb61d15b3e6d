//! Frames are written on their own thread while the next frame simulates: the bake hands over
//! each frame's positions (double-buffered through a channel of two) and only waits when the
//! writer falls two frames behind. The first error stops the writer and is returned to the bake.
//!
//! That pays while the GPU simulates and the CPU waits. When the CPU solver already keeps every
//! core busy, a writer thread only takes turns with it (measured on scene H with 2 cores:
//! 9.9 → 19 ms per simulated frame and a longer bake), so there frames are written in line.

use super::obj;
use crate::error::Result;
use crate::sim::model::GarmentRange;
use glam::Vec3;
use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, SyncSender};
use std::thread::JoinHandle;

/// What the bake hands the writer thread, in frame order.
enum Message {
    /// Positions of every garment (export order) on a frame.
    Frame(u32, Vec<Vec3>),
    /// The garments' faces from the next frame on (after tearing).
    Garments(Vec<GarmentRange>),
}

/// Writes OBJ frames, on its own thread or in line.
pub struct FrameWriter {
    frames: Option<SyncSender<Message>>,
    thread: Option<JoinHandle<Result<()>>>,
    /// Where to write in line (when no thread was spawned).
    inline: Option<(PathBuf, Vec<GarmentRange>)>,
}

/// Writes one frame of every garment.
fn write_all(
    dir: &std::path::Path,
    garments: &[GarmentRange],
    frame: u32,
    positions: &[Vec3],
) -> Result<()> {
    for g in garments {
        obj::write_frame(dir, g, frame, &positions[g.export.clone()])?;
    }
    Ok(())
}

impl FrameWriter {
    /// A writer that writes each frame when it is handed over.
    pub fn inline(dir: PathBuf, garments: Vec<GarmentRange>) -> FrameWriter {
        FrameWriter {
            frames: None,
            thread: None,
            inline: Some((dir, garments)),
        }
    }

    /// Starts a writer of `garments`' frames into `dir`.
    pub fn spawn(dir: PathBuf, garments: Vec<GarmentRange>) -> FrameWriter {
        let (send, receive) = sync_channel::<Message>(2);
        let thread = std::thread::spawn(move || {
            let mut garments = garments;
            for message in receive {
                match message {
                    Message::Frame(frame, positions) => {
                        write_all(&dir, &garments, frame, &positions)?
                    }
                    Message::Garments(g) => garments = g,
                }
            }
            Ok(())
        });
        FrameWriter {
            frames: Some(send),
            thread: Some(thread),
            inline: None,
        }
    }

    /// Writes later frames with these garments' faces (after tearing), in line or, queued
    /// behind the frames already handed over, on the writer thread.
    pub fn set_garments(&mut self, garments: Vec<GarmentRange>) -> Result<()> {
        if let Some((_, g)) = &mut self.inline {
            *g = garments;
            return Ok(());
        }
        self.send(Message::Garments(garments))
    }

    /// Hands `message` to the thread; fails with the writer's error if it stopped.
    fn send(&mut self, message: Message) -> Result<()> {
        let sent = self
            .frames
            .as_ref()
            .is_some_and(|s| s.send(message).is_ok());
        if sent {
            Ok(())
        } else {
            self.finish()
        }
    }

    /// Queues frame `frame` (positions in export order). Fails with the writer's error if it
    /// stopped.
    pub fn write(&mut self, frame: u32, positions: Vec<Vec3>) -> Result<()> {
        if let Some((dir, garments)) = &self.inline {
            return write_all(dir, garments, frame, &positions);
        }
        self.send(Message::Frame(frame, positions))
    }

    /// Waits until every queued frame is written.
    pub fn finish(&mut self) -> Result<()> {
        self.frames = None;
        match self.thread.take() {
            Some(t) => t.join().expect("the frame writer does not panic"),
            None => Ok(()),
        }
    }
}

impl Drop for FrameWriter {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}
