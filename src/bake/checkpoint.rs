//! Checkpoints: what a bake writes so that it can be resumed, bit for bit, after an interrupt,
//! a crash or a pre-emption, or continued when more frames are asked for.
//!
//! `checkpoints/` in the output folder holds:
//! - `frames.bin`: every baked frame's garment positions (export order, `f32`), and the faces
//!   of a garment whenever tearing changed them: a resumed bake replays these into fresh
//!   exports instead of simulating them again, so every output format resumes the same way;
//! - `frame_NNNN.ckpt`: the simulation's [`Snapshot`] after shot frame NNNN with the bake's
//!   running measures ([`Progress`]), written every `checkpoint_every` frames (by default about
//!   every 10 s of baking) and always at the end;
//! - `scene.json`: the scene the checkpoints belong to (what a refusal names the difference
//!   against).
//!
//! A checkpoint file is written beside its name and renamed into place, and ends in a
//! checksum: a bake killed while writing one leaves the previous ones whole.

use crate::character::cache::{fnv, FNV_OFFSET};
use crate::collide::Penetration;
use crate::error::{Error, Result};
use crate::report::{FrameMetrics, FramePenetrations, MeshPenetration};
use crate::scene::Scene;
use crate::sim::metrics::Energy;
use crate::sim::snapshot::{Snapshot, TornGarment};
use glam::{Vec3, Vec4};
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The folder inside a bake.
pub const FOLDER: &str = "checkpoints";
const CHECKPOINT_MAGIC: &[u8; 8] = b"DRAPECKP";
const FRAMES_MAGIC: &[u8; 8] = b"DRAPEFRM";
const VERSION: u32 = 1;
/// Without `checkpoint_every`, a checkpoint after the first frame that ends this long after the
/// previous one.
pub const DEFAULT_INTERVAL: Duration = Duration::from_secs(10);

/// The frame loop's running measures: what the report sums up at the end, carried through a
/// checkpoint so a resumed bake reports every frame.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Progress {
    /// Frames baked so far.
    pub baked: u32,
    /// FNV-1a over every baked frame's positions so far.
    pub hash: u64,
    pub frame_ms: Vec<f64>,
    /// Bytes written to the GPU so far.
    pub uploaded: u64,
    /// Compute dispatches and queue submissions on the GPU so far.
    pub dispatched: u64,
    pub submitted: u64,
    pub residuals: Vec<Vec<f64>>,
    /// Worst penetration of each collider, then each shell, so far.
    pub worst: Vec<Penetration>,
    /// Energy at the start (the stability rule's reference).
    pub initial_energy: Energy,
    /// The report's per-frame fields so far.
    pub measured: Measured,
    /// With accuracy targets, or a budget left to drape: the budget's state and every frame's
    /// budget so far.
    pub budget: super::budget::BudgetState,
    pub budget_frames: Vec<super::budget::FrameBudget>,
}

/// The report's per-frame fields.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Measured {
    pub penetrations_per_frame: Vec<FramePenetrations>,
    pub worst_mesh_penetrations: Vec<MeshPenetration>,
    pub mesh_penetrations_per_frame: Vec<FramePenetrations>,
    /// Absent in checkpoints of drape before the held particles' count.
    #[serde(default)]
    pub worst_held_mesh_penetrations: Vec<MeshPenetration>,
    #[serde(default)]
    pub held_mesh_penetrations_per_frame: Vec<FramePenetrations>,
    /// Absent in checkpoints of drape before the crossing count.
    #[serde(default)]
    pub crossings_per_frame: Vec<crate::report::FrameCrossings>,
    /// Absent in checkpoints of drape before characters' own crossings were counted.
    #[serde(default)]
    pub character_crossings_per_frame: Vec<crate::report::FrameSelfCrossings>,
    /// Absent in checkpoints of drape before the strain limit.
    #[serde(default)]
    pub strain_limited_per_frame: Vec<crate::report::FrameStrainLimited>,
    /// Absent in checkpoints of drape before forced strain was counted.
    #[serde(default)]
    pub forced_strain_per_frame: Vec<crate::report::FrameForcedStrain>,
    /// Absent in checkpoints of drape before characters in colliders were measured.
    #[serde(default)]
    pub character_in_colliders_per_frame: Vec<crate::report::FrameCharacterDepth>,
    pub worst_frame: Option<FrameMetrics>,
    pub last_frame: Option<FrameMetrics>,
    /// The pre-roll's report so far (absent in checkpoints of bakes without one).
    #[serde(default)]
    pub preroll: Option<crate::report::PrerollReport>,
}

/// What identifies the bake a checkpoint belongs to, and where it stands.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Meta {
    pub drape_version: String,
    /// FNV-1a of the scene's canonical text ([`canonical_scene`]).
    pub scene_hash: String,
    /// FNV-1a of the characters' shell frames up to this checkpoint ([`characters_hashes`]).
    pub characters_hash: String,
    /// `cpu` or `gpu`.
    pub backend: String,
    /// Shot number of the last frame baked.
    pub frame: u32,
    /// Length of `frames.bin` holding exactly the frames baked.
    pub frames_bytes: u64,
    pub elapsed_substeps: u64,
    /// The substeps per frame `elapsed_substeps` counts in (absent in checkpoints of drape
    /// before it recorded them: 0, the scene's).
    #[serde(default)]
    pub substeps: u32,
    /// The driven speed's bits (exact).
    pub driven_speed_bits: u32,
    pub torn_springs: usize,
    /// The force fields' work's bits (exact; absent in checkpoints of drape before force
    /// fields: none).
    #[serde(default)]
    pub force_work_bits: u64,
    /// The particles' storage order ([`crate::sim::model::Model::layout`], hex; absent in
    /// checkpoints of drape before it recorded it).
    #[serde(default)]
    pub layout: Option<String>,
    pub progress: Progress,
}

/// A checkpoint read back.
pub struct Loaded {
    pub meta: Meta,
    pub snapshot: Snapshot,
}

/// The scene as far as it decides the frames: everything but how many frames, what is written,
/// where it runs and how often checkpoints are taken; fields that are null or empty lists are
/// left out, so a drape that adds an optional field still resumes an older bake's checkpoints.
pub fn canonical_scene(scene: &Scene) -> serde_json::Value {
    let mut value = serde_json::to_value(scene).expect("scenes serialise");
    if let Some(map) = value.as_object_mut() {
        for key in ["frames", "output", "backend", "checkpoint_every"] {
            map.remove(key);
        }
        // `solver.iterations` reads the same given or not, but left out it leaves drape the
        // budget (`bake::budget`): only then marked, so checkpoints of scenes that give it, made
        // before the mark, still resume.
        let solver = map.get_mut("solver").and_then(|s| s.as_object_mut());
        if let Some(solver) = solver.filter(|_| !scene.iterations_given) {
            solver.insert("iterations_left_to_drape".into(), true.into());
        }
    }
    prune(&mut value);
    value
}

/// Removes null and empty-list members of every object in `value`.
fn prune(value: &mut serde_json::Value) {
    match value {
        serde_json::Value::Object(map) => {
            map.retain(|_, v| !(v.is_null() || v.as_array().is_some_and(Vec::is_empty)));
            map.values_mut().for_each(prune);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(prune),
        _ => {}
    }
}

/// The scene's canonical text ([`canonical_scene`]) and its hex FNV-1a.
pub fn scene_identity(scene: &Scene) -> (String, String) {
    let text = serde_json::to_string_pretty(&canonical_scene(scene)).expect("values serialise");
    let hash = format!("{:016x}", fnv(FNV_OFFSET, text.as_bytes()));
    (text, hash)
}

/// FNV-1a of the characters' shells (names and radii, then every shell's positions frame by
/// frame) through each frame: entry k covers frames 0 (the start) to k, what a state after k
/// baked frames depends on. Computed once per bake; a checkpoint looks its frame up.
pub fn characters_hashes(shells: &[crate::collide::ShellCollider]) -> Vec<String> {
    let mut h = FNV_OFFSET;
    for s in shells {
        h = fnv(h, s.name.as_bytes());
        h = fnv(h, &s.radius.to_le_bytes());
    }
    let frames = shells
        .iter()
        .map(|s| s.frames.len())
        .max()
        .unwrap_or(0)
        .max(1);
    (0..frames)
        .map(|k| {
            for frame in shells.iter().filter_map(|s| s.frames.get(k)) {
                h = fnv(h, bytemuck::cast_slice(frame));
            }
            format!("{h:016x}")
        })
        .collect()
}

/// Entry `baked` of [`characters_hashes`] (the last one past the characters' frames).
pub fn characters_hash(hashes: &[String], baked: u32) -> &str {
    &hashes[(baked as usize).min(hashes.len() - 1)]
}

/// The checkpoint file of shot frame `frame`.
pub fn file_name(frame: u32) -> String {
    format!("frame_{frame:04}.ckpt")
}

/// The checkpoints in `folder` (a bake's `checkpoints/`), by frame.
pub fn list(folder: &Path) -> Vec<(u32, PathBuf)> {
    let mut found: Vec<(u32, PathBuf)> = std::fs::read_dir(folder)
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            let frame = name.strip_prefix("frame_")?.strip_suffix(".ckpt")?;
            Some((frame.parse().ok()?, e.path()))
        })
        .collect();
    found.sort();
    found
}

/// Writes the checkpoints of one bake into `folder`.
pub struct Writer {
    folder: PathBuf,
    frames: FramesLog,
    /// `checkpoint_every` (None: by time).
    every: Option<u32>,
    last: Instant,
    /// The scene's hash and the backend.
    identity: (String, String),
    /// [`characters_hashes`] of the bake's shells.
    characters: Vec<String>,
    /// Checkpoints written: (frame, bytes, milliseconds).
    pub written: Vec<(u32, u64, f64)>,
}

impl Writer {
    /// Starts `folder` (created) for `scene` with `vertices` garment positions per frame.
    pub fn create(
        folder: PathBuf,
        scene: &Scene,
        backend: &str,
        vertices: usize,
        shells: &[crate::collide::ShellCollider],
    ) -> Result<Writer> {
        std::fs::create_dir_all(&folder).map_err(|e| Error::io(&folder, "cannot create", e))?;
        let (text, scene_hash) = scene_identity(scene);
        let scene_path = folder.join("scene.json");
        std::fs::write(&scene_path, &text)
            .map_err(|e| Error::io(&scene_path, "cannot write", e))?;
        Ok(Writer {
            frames: FramesLog::create(folder.join("frames.bin"), vertices)?,
            folder,
            every: scene.checkpoint_every,
            last: Instant::now(),
            identity: (scene_hash, backend.into()),
            characters: characters_hashes(shells),
            written: Vec::new(),
        })
    }

    /// Logs baked frame `index`'s garment positions.
    pub fn frame(&mut self, index: u32, positions: &[Vec3]) -> Result<()> {
        self.frames.frame(index, positions)
    }

    /// Logs garment `g`'s faces from baked frame `index` on.
    pub fn faces(&mut self, g: usize, index: u32, faces: &[[u32; 3]]) -> Result<()> {
        self.frames.faces(g, index, faces)
    }

    /// True when a checkpoint is due after `baked` frames.
    pub fn due(&self, baked: u32) -> bool {
        match self.every {
            Some(n) => n > 0 && baked % n == 0,
            None => self.last.elapsed() >= DEFAULT_INTERVAL,
        }
    }

    /// What the report says of this run's checkpoints.
    pub fn report(&self) -> crate::report::CheckpointReport {
        crate::report::CheckpointReport {
            frames: self.written.iter().map(|w| w.0).collect(),
            bytes: self.written.last().map_or(0, |w| w.1),
            ms: self.written.iter().map(|w| w.2).sum(),
            frames_log_bytes: self.frames.bytes,
        }
    }

    /// Writes the checkpoint after shot frame `frame` (unless it is written already).
    pub fn write(&mut self, frame: u32, snapshot: &Snapshot, progress: &Progress) -> Result<()> {
        if self.written.last().is_some_and(|w| w.0 == frame) {
            return Ok(());
        }
        let start = Instant::now();
        let frames_bytes = self.frames.flush()?;
        let meta = Meta {
            drape_version: env!("CARGO_PKG_VERSION").into(),
            scene_hash: self.identity.0.clone(),
            characters_hash: characters_hash(&self.characters, progress.baked).to_string(),
            backend: self.identity.1.clone(),
            frame,
            frames_bytes,
            elapsed_substeps: snapshot.elapsed_substeps,
            substeps: snapshot.substeps,
            driven_speed_bits: snapshot.driven_speed.to_bits(),
            torn_springs: snapshot.torn_springs,
            force_work_bits: snapshot.force_work.to_bits(),
            layout: snapshot.layout.map(|l| format!("{l:016x}")),
            progress: progress.clone(),
        };
        let bytes = encode(&meta, snapshot);
        let path = self.folder.join(file_name(frame));
        let partial = path.with_extension("ckpt.partial");
        let written = (|| {
            let mut f = File::create(&partial)?;
            f.write_all(&bytes)?;
            f.sync_data()?;
            std::fs::rename(&partial, &path)
        })();
        written.map_err(|e| Error::io(&path, "cannot write", e))?;
        self.last = Instant::now();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        self.written.push((frame, bytes.len() as u64, ms));
        Ok(())
    }
}

fn push_u32(b: &mut Vec<u8>, v: u32) {
    b.extend_from_slice(&v.to_le_bytes());
}

fn push_u64(b: &mut Vec<u8>, v: u64) {
    b.extend_from_slice(&v.to_le_bytes());
}

fn push_slice<T: bytemuck::Pod>(b: &mut Vec<u8>, items: &[T]) {
    push_u64(b, items.len() as u64);
    b.extend_from_slice(bytemuck::cast_slice(items));
}

/// magic, version, meta (JSON), positions, velocities, nearby, torn garments, checksum.
fn encode(meta: &Meta, s: &Snapshot) -> Vec<u8> {
    let json = serde_json::to_vec(meta).expect("metadata serialises");
    let mut b = Vec::with_capacity(json.len() + s.positions.len() * 32 + 64);
    b.extend_from_slice(CHECKPOINT_MAGIC);
    push_u32(&mut b, VERSION);
    push_u64(&mut b, json.len() as u64);
    b.extend_from_slice(&json);
    push_slice(&mut b, &s.positions);
    push_slice(&mut b, &s.velocities);
    push_slice(&mut b, &s.nearby);
    push_u64(&mut b, s.torn.len() as u64);
    for t in &s.torn {
        push_u64(&mut b, t.garment as u64);
        push_u32(&mut b, t.tethers as u32);
        push_slice(&mut b, &t.springs);
        push_slice(&mut b, &t.triangles);
    }
    let checksum = fnv(FNV_OFFSET, &b);
    push_u64(&mut b, checksum);
    b
}

/// A cursor over a checkpoint's bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize) -> std::result::Result<&[u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or("it ends early")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u32(&mut self) -> std::result::Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }

    fn u64(&mut self) -> std::result::Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }

    fn slice<T: bytemuck::Pod>(&mut self) -> std::result::Result<Vec<T>, String> {
        let n = usize::try_from(self.u64()?).map_err(|_| "a count is too large")?;
        let bytes = n
            .checked_mul(std::mem::size_of::<T>())
            .ok_or("a count is too large")?;
        Ok(bytemuck::pod_collect_to_vec(self.take(bytes)?))
    }
}

/// Reads the checkpoint at `path`; the error says what is wrong with the file.
pub fn load(path: &Path) -> Result<Loaded> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
    decode(&bytes).map_err(|reason| Error::InvalidField {
        file: path.display().to_string(),
        field: "checkpoint".into(),
        reason,
    })
}

fn decode(bytes: &[u8]) -> std::result::Result<Loaded, String> {
    if bytes.len() < 20 || &bytes[..8] != CHECKPOINT_MAGIC {
        return Err("not a drape checkpoint".into());
    }
    let (body, tail) = bytes.split_at(bytes.len() - 8);
    if fnv(FNV_OFFSET, body).to_le_bytes() != tail {
        return Err("its checksum does not match (a damaged or partly written file)".into());
    }
    let mut c = Cursor { bytes: body, at: 8 };
    let version = c.u32()?;
    if version != VERSION {
        return Err(format!(
            "written in format {version}; this drape reads {VERSION}"
        ));
    }
    let json_len = usize::try_from(c.u64()?).map_err(|_| "too large")?;
    let meta: Meta = serde_json::from_slice(c.take(json_len)?).map_err(|e| e.to_string())?;
    let positions: Vec<Vec4> = c.slice()?;
    let velocities: Vec<Vec4> = c.slice()?;
    let nearby = c.slice()?;
    let mut torn = Vec::new();
    for _ in 0..c.u64()? {
        torn.push(TornGarment {
            garment: c.u64()? as usize,
            tethers: c.u32()? != 0,
            springs: c.slice()?,
            triangles: c.slice()?,
        });
    }
    let snapshot = Snapshot {
        positions,
        velocities,
        elapsed_substeps: meta.elapsed_substeps,
        substeps: meta.substeps,
        driven_speed: f32::from_bits(meta.driven_speed_bits),
        torn_springs: meta.torn_springs,
        force_work: f64::from_bits(meta.force_work_bits),
        torn,
        nearby,
        layout: match &meta.layout {
            Some(hex) => Some(u64::from_str_radix(hex, 16).map_err(|e| format!("layout: {e}"))?),
            None => None,
        },
    };
    Ok(Loaded { meta, snapshot })
}

/// `frames.bin`: a header (magic, version, positions per frame), then records: a frame
/// (tag 0, baked index, positions) or a garment's new faces (tag 1, garment, baked index,
/// count, faces).
pub struct FramesLog {
    path: PathBuf,
    out: BufWriter<File>,
    vertices: usize,
    bytes: u64,
}

impl FramesLog {
    fn create(path: PathBuf, vertices: usize) -> Result<FramesLog> {
        let file = File::create(&path).map_err(|e| Error::io(&path, "cannot create", e))?;
        let mut log = FramesLog {
            out: BufWriter::with_capacity(1 << 20, file),
            path,
            vertices,
            bytes: 0,
        };
        let mut header = FRAMES_MAGIC.to_vec();
        push_u32(&mut header, VERSION);
        push_u64(&mut header, vertices as u64);
        log.write(&header)?;
        Ok(log)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<()> {
        self.out
            .write_all(bytes)
            .map_err(|e| Error::io(&self.path, "cannot write", e))?;
        self.bytes += bytes.len() as u64;
        Ok(())
    }

    fn frame(&mut self, index: u32, positions: &[Vec3]) -> Result<()> {
        debug_assert_eq!(positions.len(), self.vertices);
        let mut head = vec![0u8];
        push_u32(&mut head, index);
        self.write(&head)?;
        self.write(bytemuck::cast_slice(positions))
    }

    fn faces(&mut self, g: usize, index: u32, faces: &[[u32; 3]]) -> Result<()> {
        let mut head = vec![1u8];
        push_u32(&mut head, g as u32);
        push_u32(&mut head, index);
        push_slice(&mut head, faces);
        self.write(&head)
    }

    /// Flushes to the disk; returns the length written.
    fn flush(&mut self) -> Result<u64> {
        let io = |e| Error::io(&self.path, "cannot write", e);
        self.out.flush().map_err(io)?;
        self.out.get_ref().sync_data().map_err(io)?;
        Ok(self.bytes)
    }
}

/// One record of `frames.bin`.
pub enum Record {
    Frame {
        index: u32,
        positions: Vec<Vec3>,
    },
    Faces {
        garment: usize,
        index: u32,
        faces: Vec<[u32; 3]>,
    },
}

/// Reads `frames.bin` at `path` up to byte `end`, calling `each` on every record in order.
pub fn replay(
    path: &Path,
    end: u64,
    vertices: usize,
    mut each: impl FnMut(Record) -> Result<()>,
) -> Result<()> {
    let bad = |reason: String| Error::InvalidField {
        file: path.display().to_string(),
        field: "frames".into(),
        reason,
    };
    let file = File::open(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let mut r = std::io::BufReader::with_capacity(1 << 20, file.take(end));
    let mut read = |n: usize| -> Result<Vec<u8>> {
        let mut b = vec![0u8; n];
        r.read_exact(&mut b)
            .map_err(|_| bad("it ends before the checkpoint's last frame".into()))?;
        Ok(b)
    };
    let header = read(20)?;
    if &header[..8] != FRAMES_MAGIC
        || u64::from_le_bytes(header[12..20].try_into().expect("8 bytes")) != vertices as u64
    {
        return Err(bad(format!(
            "not the frames log of a bake with {vertices} garment vertices"
        )));
    }
    let mut at = 20u64;
    let word = |b: &[u8]| u32::from_le_bytes(b.try_into().expect("4 bytes"));
    while at < end {
        let head = read(5)?;
        at += 5;
        if head[0] == 0 {
            let positions = bytemuck::pod_collect_to_vec(&read(vertices * 12)?);
            at += vertices as u64 * 12;
            each(Record::Frame {
                index: word(&head[1..5]),
                positions,
            })?;
        } else {
            let rest = read(12)?;
            let count = u64::from_le_bytes(rest[4..12].try_into().expect("8 bytes"));
            let bytes = usize::try_from(count.saturating_mul(12))
                .ok()
                .filter(|&b| b as u64 <= end.saturating_sub(at))
                .ok_or_else(|| bad("a face count runs past the checkpoint's frames".into()))?;
            let faces = bytemuck::pod_collect_to_vec(&read(bytes)?);
            at += 12 + bytes as u64;
            each(Record::Faces {
                garment: word(&head[1..5]) as usize,
                index: word(&rest[0..4]),
                faces,
            })?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snapshot() -> Snapshot {
        Snapshot {
            positions: vec![Vec4::new(1.0, 2.0, 3.0, 0.0); 3],
            velocities: vec![Vec4::new(-0.5, 0.25, f32::MIN_POSITIVE, 0.0); 3],
            elapsed_substeps: 123,
            substeps: 41,
            driven_speed: 0.1,
            torn_springs: 2,
            force_work: 0.5,
            torn: vec![TornGarment {
                garment: 0,
                springs: vec![[0, 1]],
                triangles: vec![[0, 1, 2]],
                tethers: false,
            }],
            nearby: vec![[7; crate::collide::shell::NEARBY]; 3],
            layout: Some(0x0123_4567_89ab_cdef),
        }
    }

    fn meta() -> Meta {
        Meta {
            drape_version: "test".into(),
            scene_hash: "a".into(),
            characters_hash: "b".into(),
            backend: "cpu".into(),
            frame: 1001,
            frames_bytes: 20,
            elapsed_substeps: 123,
            substeps: 41,
            driven_speed_bits: 0.1f32.to_bits(),
            torn_springs: 2,
            force_work_bits: 0.5f64.to_bits(),
            layout: Some("0123456789abcdef".into()),
            progress: Progress {
                frame_ms: vec![0.1 + 0.2, 1e-300],
                ..Progress::default()
            },
        }
    }

    #[test]
    fn a_checkpoint_reads_back_exactly() {
        let loaded = decode(&encode(&meta(), &snapshot())).unwrap();
        assert_eq!(loaded.snapshot, snapshot());
        assert_eq!(loaded.meta.progress.frame_ms, meta().progress.frame_ms);
        assert_eq!(loaded.meta.frame, 1001);
    }

    #[test]
    fn a_damaged_or_short_checkpoint_is_refused_with_the_reason() {
        let bytes = encode(&meta(), &snapshot());
        let mut flipped = bytes.clone();
        flipped[40] ^= 1;
        assert!(decode(&flipped).err().unwrap().contains("checksum"));
        assert!(decode(&bytes[..bytes.len() / 2]).is_err());
        assert!(decode(b"not a checkpoint at all")
            .err()
            .unwrap()
            .contains("not a drape checkpoint"));
    }
}
