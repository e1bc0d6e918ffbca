//! The bake directory: simplified scene, time list and solutions on disk,
//! so that a walk-through can reuse indirect light computed once. The
//! format is described in `docs/bake-format.md`.
//!
//! A bake is written into `<dir>.partial` and renamed into place when
//! complete, so a directory named `<dir>` is always a finished bake. Every
//! number is stored with its exact bits (little-endian binary arrays; the
//! manifest's floats are printed in shortest round-trip form), so loading
//! gives back exactly what was saved.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, ensure, Context, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::checksum::{fnv1a64, hex};
use crate::output::{Contents, Folder};
use crate::scene::hash::ContentHash;
use crate::scene::Scene;

use super::temporal::{DecomposeStats, IntervalTest, TimeSeries};
use super::{IndirectSolution, Patch, Quality, RecordPoint, Simplified, SimplifyStats, SolveStats};

/// Identifies a bake manifest.
pub const FORMAT: &str = "rangewalk-bake";
/// Bumped whenever the layout changes; older or newer bakes are refused.
pub const VERSION: u32 = 4;
pub const MANIFEST: &str = "manifest.toml";
const PATCHES: &str = "patches.bin";
const RECORDS: &str = "records.bin";
const IRRADIANCE: &str = "irradiance.bin";
const PRUNED: &str = "pruned.bin";
/// What a store holds: it is replaced whole, and only while it holds
/// nothing else.
const CONTENTS: Contents = Contents {
    what: "a radiosity store",
    owns: |name, is_dir| {
        !is_dir && [MANIFEST, PATCHES, RECORDS, IRRADIANCE, PRUNED].contains(&name)
    },
};
/// Bytes per stored element.
const PATCH_BYTES: usize = 4 * (1 + 9 + 3 + 3 + 3 + 3 + 1);
const RECORD_BYTES: usize = 4 * (1 + 3 + 3);
const PRUNED_BYTES: usize = 4 * 2;
const VEC_BYTES: usize = 12;

#[derive(Serialize, Deserialize)]
struct Manifest {
    format: String,
    version: u32,
    /// The scene the bake was made from, as given when it was made.
    scene: PathBuf,
    quality: Quality,
    times: Vec<f32>,
    /// The scene's content when the bake was made: a bake is only used for
    /// the scene it was solved for.
    scene_hash: ContentHash,
    simplify: SimplifyEntry,
    decompose: DecomposeEntry,
    solutions: Vec<SolutionEntry>,
    files: Files,
}

#[derive(Serialize, Deserialize)]
struct SimplifyEntry {
    initial_surfaces: u64,
    pruned_surfaces: u64,
    final_surfaces: u64,
    visibility_rays: u64,
    seconds: f64,
}

#[derive(Serialize, Deserialize)]
struct DecomposeEntry {
    solves: u64,
    depth: u32,
    max_depth: u32,
    static_scene: bool,
    seconds: f64,
    intervals: Vec<IntervalEntry>,
}

#[derive(Serialize, Deserialize)]
struct IntervalEntry {
    t0: f32,
    t1: f32,
    depth: u32,
    relative_rms: f64,
    unchanged: f64,
    split: bool,
}

#[derive(Serialize, Deserialize)]
struct SolutionEntry {
    time: f32,
    elements: u64,
    links: u64,
    iterations: u64,
    residual: f64,
    shadow_rays: u64,
    seconds: f64,
}

#[derive(Serialize, Deserialize)]
struct Files {
    patches: FileEntry,
    records: FileEntry,
    irradiance: FileEntry,
    pruned: FileEntry,
}

/// One binary file: how many elements, how many bytes, and a checksum that
/// catches corruption the length cannot.
#[derive(Serialize, Deserialize)]
struct FileEntry {
    name: String,
    count: u64,
    bytes: u64,
    fnv1a64: String,
}

/// The bake's provenance, for checking that it fits the scene in hand.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeInfo {
    pub scene: PathBuf,
    pub quality: Quality,
    pub scene_hash: ContentHash,
}

/// Writes `simplified` and `series`, solved for `scene`, under `dir`,
/// replacing an earlier bake there. The scene's file and content hash are
/// recorded, so that [`load_for`] can refuse the bake for another scene.
pub fn save(dir: &Path, scene: &Scene, simplified: &Simplified, series: &TimeSeries) -> Result<()> {
    let scene_hash = ContentHash::of(scene)?;
    let n = simplified.records.len();
    ensure!(
        series.times.len() == series.solutions.len(),
        "bake: {} times but {} solutions",
        series.times.len(),
        series.solutions.len()
    );
    for s in &series.solutions {
        ensure!(
            s.indirect.len() == n && s.direct.len() == n,
            "bake: the solution at t = {} has {} indirect and {} direct values for {n} records",
            s.time,
            s.indirect.len(),
            s.direct.len()
        );
    }
    let folder = Folder::begin(dir, CONTENTS)?;

    let patches = encode_patches(&simplified.patches);
    let records = encode_records(&simplified.records);
    let pruned = encode_pruned(&simplified.pruned);
    let mut irradiance = Vec::with_capacity(series.solutions.len() * 2 * n * VEC_BYTES);
    for s in &series.solutions {
        put_vecs(&mut irradiance, &s.indirect);
        put_vecs(&mut irradiance, &s.direct);
    }
    let manifest = Manifest {
        format: FORMAT.to_string(),
        version: VERSION,
        scene: scene.source.clone(),
        quality: series.quality,
        times: series.times.clone(),
        scene_hash,
        simplify: simplify_entry(&simplified.stats),
        decompose: decompose_entry(&series.stats),
        solutions: series.solutions.iter().map(solution_entry).collect(),
        files: Files {
            patches: file_entry(PATCHES, simplified.patches.len(), &patches),
            records: file_entry(RECORDS, n, &records),
            irradiance: file_entry(IRRADIANCE, series.solutions.len(), &irradiance),
            pruned: file_entry(PRUNED, simplified.pruned.len(), &pruned),
        },
    };
    let text = toml::to_string(&manifest).context("bake: encoding the manifest")?;
    for (name, bytes) in [
        (PATCHES, patches.as_slice()),
        (RECORDS, &records),
        (IRRADIANCE, &irradiance),
        (PRUNED, &pruned),
        (MANIFEST, text.as_bytes()),
    ] {
        let path = folder.path().join(name);
        fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
    }
    folder.finish()?;
    Ok(())
}

/// Reads back what [`save`] wrote, identical to what was saved.
pub fn load(dir: &Path) -> Result<(Simplified, TimeSeries)> {
    load_with_info(dir).map(|(s, t, _)| (s, t))
}

/// [`load_with_info`] for `scene` (and, when given, `quality`): a bake
/// solved for a scene whose text, meshes or materials differ, or at
/// another quality, is an error saying what differs.
pub fn load_for(
    dir: &Path,
    scene: &Scene,
    quality: Option<Quality>,
) -> Result<(Simplified, TimeSeries, BakeInfo)> {
    let (simplified, series, info) = load_with_info(dir)?;
    let changes = info.scene_hash.differences(&ContentHash::of(scene)?);
    ensure!(
        changes.is_empty(),
        "{} was baked from {}, which differs from {} in {}: bake again or pass another bake directory",
        dir.display(),
        info.scene.display(),
        scene.source.display(),
        changes.join(", ")
    );
    if let Some(q) = quality.filter(|&q| q != info.quality) {
        bail!(
            "{} was baked at quality {}, not {q}: ask for quality {} or use another bake directory",
            dir.display(),
            info.quality,
            info.quality
        );
    }
    Ok((simplified, series, info))
}

/// [`load`] with the bake's provenance. Every way the store can be
/// damaged (unfinished, unreadable, truncated, corrupt, of another
/// version) is repaired the same way, which the error says: the store is
/// derived data, solved again by the next command that needs it once it
/// is gone.
pub fn load_with_info(dir: &Path) -> Result<(Simplified, TimeSeries, BakeInfo)> {
    read_store(dir).map_err(|e| {
        anyhow!(
            "{e:#}; delete {} to repair it: the next `rangewalk bake` (for a bake's radiosity/), \
             `rangewalk radiosity` or `render --indirect radiosity --bake` solves radiosity again",
            dir.display()
        )
    })
}

fn read_store(dir: &Path) -> Result<(Simplified, TimeSeries, BakeInfo)> {
    let mpath = dir.join(MANIFEST);
    if !mpath.exists() && partial_path(dir).exists() {
        bail!(
            "{}: the bake was never finished (only {} exists)",
            dir.display(),
            partial_path(dir).display()
        );
    }
    let text =
        fs::read_to_string(&mpath).with_context(|| format!("reading {}", mpath.display()))?;
    let m: Manifest = toml::from_str(&text).with_context(|| format!("{}", mpath.display()))?;
    let at = |field: &str| format!("{}: field `{field}`", mpath.display());
    ensure!(
        m.format == FORMAT,
        "{}: is `{}`, not `{FORMAT}`",
        at("format"),
        m.format
    );
    ensure!(
        m.version == VERSION,
        "{}: version {} is not supported (this build reads version {VERSION}); bake again",
        at("version"),
        m.version
    );
    ensure!(
        m.times.len() == m.solutions.len(),
        "{}: {} times but {} solutions",
        at("times"),
        m.times.len(),
        m.solutions.len()
    );
    ensure!(
        m.times.iter().all(|t| t.is_finite()) && m.times.windows(2).all(|w| w[0] < w[1]),
        "{}: times {:?} are not finite and strictly increasing",
        at("times"),
        m.times
    );

    let patches_raw = read_checked(dir, &m.files.patches, PATCH_BYTES, "files.patches")?;
    let records_raw = read_checked(dir, &m.files.records, RECORD_BYTES, "files.records")?;
    let n = m.files.records.count as usize;
    let irr_raw = read_checked(
        dir,
        &m.files.irradiance,
        2 * n * VEC_BYTES,
        "files.irradiance",
    )?;
    ensure!(
        m.files.irradiance.count as usize == m.solutions.len(),
        "{}: {} solutions stored for {} listed",
        at("files.irradiance.count"),
        m.files.irradiance.count,
        m.solutions.len()
    );

    let pruned_raw = read_checked(dir, &m.files.pruned, PRUNED_BYTES, "files.pruned")?;
    let pruned = decode_pruned(&pruned_raw);
    if let Some(k) = pruned.windows(2).position(|w| w[0] >= w[1]) {
        bail!(
            "{}: entry {} {:?} does not follow {:?}: entries must ascend",
            dir.join(PRUNED).display(),
            k + 1,
            pruned[k + 1],
            pruned[k]
        );
    }
    let records = decode_records(&records_raw);
    let patches = decode_patches(&patches_raw);
    let pfile = dir.join(PATCHES);
    for (i, p) in patches.iter().enumerate() {
        if let Some(c) = p.corners.iter().chain(&p.back).find(|&&c| c as usize >= n) {
            bail!(
                "{}: patch {i} names record {c}, but there are {n} records",
                pfile.display()
            );
        }
    }
    let mut vecs = get_vecs(&irr_raw);
    let mut solutions = Vec::with_capacity(m.solutions.len());
    for (k, e) in m.solutions.iter().enumerate() {
        let indirect: Vec<Vec3> = vecs.by_ref().take(n).collect();
        let direct: Vec<Vec3> = vecs.by_ref().take(n).collect();
        if let Some(i) = indirect.iter().chain(&direct).position(|v| !v.is_finite()) {
            bail!(
                "{}: solution {k} (t = {}) holds a non-finite irradiance at value {i}",
                dir.join(IRRADIANCE).display(),
                e.time
            );
        }
        solutions.push(IndirectSolution {
            time: e.time,
            indirect,
            direct,
            stats: SolveStats {
                elements: e.elements as usize,
                links: e.links as usize,
                iterations: e.iterations as usize,
                residual: e.residual,
                shadow_rays: e.shadow_rays,
                seconds: e.seconds,
            },
        });
    }
    let s = &m.simplify;
    let simplified = Simplified {
        patches,
        records,
        pruned,
        stats: SimplifyStats {
            initial_surfaces: s.initial_surfaces as usize,
            pruned_surfaces: s.pruned_surfaces as usize,
            final_surfaces: s.final_surfaces as usize,
            visibility_rays: s.visibility_rays,
            seconds: s.seconds,
        },
    };
    let d = &m.decompose;
    let series = TimeSeries {
        times: m.times.clone(),
        solutions,
        quality: m.quality,
        stats: DecomposeStats {
            solves: d.solves as usize,
            depth: d.depth,
            max_depth: d.max_depth,
            static_scene: d.static_scene,
            intervals: d
                .intervals
                .iter()
                .map(|i| IntervalTest {
                    t0: i.t0,
                    t1: i.t1,
                    depth: i.depth,
                    relative_rms: i.relative_rms,
                    unchanged: i.unchanged,
                    split: i.split,
                })
                .collect(),
            seconds: d.seconds,
        },
    };
    let info = BakeInfo {
        scene: m.scene,
        quality: m.quality,
        scene_hash: m.scene_hash,
    };
    Ok((simplified, series, info))
}

/// `<dir>.partial`, beside `dir`.
pub fn partial_path(dir: &Path) -> PathBuf {
    let mut name = dir.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    dir.with_file_name(name)
}

/// Reads a binary file and checks it against its manifest entry: length,
/// element size and checksum.
fn read_checked(dir: &Path, e: &FileEntry, elem: usize, field: &str) -> Result<Vec<u8>> {
    let path = dir.join(&e.name);
    ensure!(
        Path::new(&e.name).file_name() == Some(e.name.as_ref()),
        "{}: field `{field}.name` = {:?} is not a plain file name",
        dir.join(MANIFEST).display(),
        e.name
    );
    let bytes = fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    let expect = (e.count as usize)
        .checked_mul(elem)
        .filter(|&b| b as u64 == e.bytes)
        .ok_or_else(|| {
            anyhow!(
                "{}: field `{field}`: {} elements of {elem} bytes is not {} bytes",
                dir.join(MANIFEST).display(),
                e.count,
                e.bytes
            )
        })?;
    ensure!(
        bytes.len() == expect,
        "{}: {} bytes, but `{field}` in {MANIFEST} says {expect} ({} elements); the file is truncated or from another bake",
        path.display(),
        bytes.len(),
        e.count
    );
    let sum = hex(fnv1a64(&bytes));
    ensure!(
        sum == e.fnv1a64,
        "{}: checksum {sum} differs from `{field}.fnv1a64` = {} in {MANIFEST}; the file is corrupt",
        path.display(),
        e.fnv1a64
    );
    Ok(bytes)
}

fn file_entry(name: &str, count: usize, bytes: &[u8]) -> FileEntry {
    FileEntry {
        name: name.to_string(),
        count: count as u64,
        bytes: bytes.len() as u64,
        fnv1a64: hex(fnv1a64(bytes)),
    }
}

fn simplify_entry(s: &SimplifyStats) -> SimplifyEntry {
    SimplifyEntry {
        initial_surfaces: s.initial_surfaces as u64,
        pruned_surfaces: s.pruned_surfaces as u64,
        final_surfaces: s.final_surfaces as u64,
        visibility_rays: s.visibility_rays,
        seconds: s.seconds,
    }
}

fn decompose_entry(d: &DecomposeStats) -> DecomposeEntry {
    DecomposeEntry {
        solves: d.solves as u64,
        depth: d.depth,
        max_depth: d.max_depth,
        static_scene: d.static_scene,
        seconds: d.seconds,
        intervals: d
            .intervals
            .iter()
            .map(|i| IntervalEntry {
                t0: i.t0,
                t1: i.t1,
                depth: i.depth,
                relative_rms: i.relative_rms,
                unchanged: i.unchanged,
                split: i.split,
            })
            .collect(),
    }
}

fn solution_entry(s: &IndirectSolution) -> SolutionEntry {
    SolutionEntry {
        time: s.time,
        elements: s.stats.elements as u64,
        links: s.stats.links as u64,
        iterations: s.stats.iterations as u64,
        residual: s.stats.residual,
        shadow_rays: s.stats.shadow_rays,
        seconds: s.stats.seconds,
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_vec(out: &mut Vec<u8>, v: Vec3) {
    for c in v.to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

fn put_vecs(out: &mut Vec<u8>, vs: &[Vec3]) {
    for &v in vs {
        put_vec(out, v);
    }
}

fn encode_patches(patches: &[Patch]) -> Vec<u8> {
    let mut out = Vec::with_capacity(patches.len() * PATCH_BYTES);
    for p in patches {
        put_u32(&mut out, p.object);
        for v in p.vertices {
            put_vec(&mut out, v);
        }
        for c in p.corners.into_iter().chain(p.back) {
            put_u32(&mut out, c);
        }
        put_vec(&mut out, p.reflectance);
        put_vec(&mut out, p.emission);
        put_u32(&mut out, p.two_sided as u32);
    }
    out
}

fn encode_records(records: &[RecordPoint]) -> Vec<u8> {
    let mut out = Vec::with_capacity(records.len() * RECORD_BYTES);
    for r in records {
        put_u32(&mut out, r.object);
        put_vec(&mut out, r.position);
        put_vec(&mut out, r.normal);
    }
    out
}

/// Little-endian 32-bit words of a buffer whose length is a multiple of 4.
fn words(bytes: &[u8]) -> impl Iterator<Item = u32> + '_ {
    bytes
        .chunks_exact(4)
        .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
}

fn get_vecs(bytes: &[u8]) -> impl Iterator<Item = Vec3> + '_ {
    bytes.chunks_exact(VEC_BYTES).map(|c| {
        let mut w = words(c).map(f32::from_bits);
        Vec3::new(
            w.next().unwrap_or_default(),
            w.next().unwrap_or_default(),
            w.next().unwrap_or_default(),
        )
    })
}

fn decode_patches(bytes: &[u8]) -> Vec<Patch> {
    bytes
        .chunks_exact(PATCH_BYTES)
        .map(|c| {
            let w: Vec<u32> = words(c).collect();
            let v = |i: usize| Vec3::new(f(w[i]), f(w[i + 1]), f(w[i + 2]));
            Patch {
                object: w[0],
                vertices: [v(1), v(4), v(7)],
                corners: [w[10], w[11], w[12]],
                back: [w[13], w[14], w[15]],
                reflectance: v(16),
                emission: v(19),
                two_sided: w[22] != 0,
            }
        })
        .collect()
}

fn encode_pruned(pruned: &[(u32, u32)]) -> Vec<u8> {
    let mut out = Vec::with_capacity(pruned.len() * PRUNED_BYTES);
    for &(object, triangle) in pruned {
        put_u32(&mut out, object);
        put_u32(&mut out, triangle);
    }
    out
}

fn decode_pruned(bytes: &[u8]) -> Vec<(u32, u32)> {
    bytes
        .chunks_exact(PRUNED_BYTES)
        .map(|c| {
            let mut w = words(c);
            (w.next().unwrap_or_default(), w.next().unwrap_or_default())
        })
        .collect()
}

fn decode_records(bytes: &[u8]) -> Vec<RecordPoint> {
    bytes
        .chunks_exact(RECORD_BYTES)
        .map(|c| {
            let w: Vec<u32> = words(c).collect();
            RecordPoint {
                object: w[0],
                position: Vec3::new(f(w[1]), f(w[2]), f(w[3])),
                normal: Vec3::new(f(w[4]), f(w[5]), f(w[6])),
            }
        })
        .collect()
}

fn f(bits: u32) -> f32 {
    f32::from_bits(bits)
}
