//! One bake per directory at a time, and the shards of one bake together.
//!
//! Two advisory file locks (`flock`: released by the kernel when their
//! holder exits or is killed, so a killed run never leaves a bake locked):
//!
//! - `.lock`, held exclusively while a run starts or checks the manifest,
//!   solves radiosity, or registers itself: these steps are short and
//!   serial, so a second run waits for them (saying whom it waits for)
//!   instead of racing to write a manifest or a radiosity bake of its own.
//!   A second run with other settings then finds the first one's manifest
//!   and is refused by the settings check.
//! - `.running/<i>-of-<n>.<host>.<pid>.<k>`, one file per run that renders or
//!   finishes, locked exclusively for the run's whole life and naming its
//!   process, host, command and shard. Under `.lock`, a starting run probes
//!   the ones whose names give a shard sharing an image with its own (a
//!   file it can lock is a dead run's, and is removed) and refuses to
//!   render images a live run renders: shards `i/n` of one count share a
//!   bake, a second full bake or a repeated shard does not. When no other
//!   run is alive, nothing else can be writing the bake, and the temporary
//!   files of killed runs are removed.
//!
//! Holder files rather than one shared lock: shards come and go
//! independently, and each refusal can name exactly the run in the way.
//! On NFS, Linux emulates `flock` with POSIX record locks, which belong to
//! a process: there the locks keep apart processes (nodes, array tasks),
//! not threads of one process.

use std::fs::{self, File, OpenOptions, TryLockError};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use super::manifest::{self, IMAGES};
use super::Shard;

/// The lock of a bake's serial steps, in the bake directory.
pub const LOCK: &str = ".lock";
/// The folder of the files of the runs in progress, in the bake directory.
pub const RUNNING: &str = ".running";

/// A process that works on a bake, as its lock file names it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    pub pid: u32,
    pub host: String,
    pub command: String,
    /// What it does: `baking`, `baking shard 1/4`, `finishing`, ...
    pub what: String,
    /// The images it renders or reads: `index` of `count`.
    pub shard_index: u32,
    pub shard_count: u32,
    /// Seconds since the Unix epoch when it started.
    pub started: u64,
}

impl Holder {
    /// This process, doing `what` to the images of `shard`.
    pub fn me(what: impl Into<String>, shard: Shard) -> Holder {
        let command: String = std::env::args().collect::<Vec<_>>().join(" ");
        const LONGEST: usize = 400;
        let command = match command.char_indices().nth(LONGEST) {
            Some((at, _)) => format!("{} ...", &command[..at]),
            None => command,
        };
        Holder {
            pid: std::process::id(),
            host: host_name(),
            command,
            what: what.into(),
            shard_index: shard.index,
            shard_count: shard.count,
            started: now(),
        }
    }

    pub fn shard(&self) -> Shard {
        Shard {
            index: self.shard_index,
            count: self.shard_count.max(1),
        }
    }

    /// Whether it and `other` have an image in common.
    pub fn overlaps(&self, other: &Holder) -> bool {
        overlap(self.shard(), other.shard())
    }
}

/// Whether two shards have an image in common: shards `i/n` and `j/m` both
/// own image `k` iff `i ≡ j (mod gcd(n, m))`.
fn overlap(a: Shard, b: Shard) -> bool {
    let g = gcd(a.count, b.count);
    a.index % g == b.index % g
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pid = if self.pid == std::process::id() && self.host == host_name() {
            format!("{} (this process)", self.pid)
        } else {
            self.pid.to_string()
        };
        write!(
            f,
            "process {pid} on {}, {} for {} s (`{}`)",
            self.host,
            self.what,
            now().saturating_sub(self.started),
            self.command
        )
    }
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a.max(1)
    } else {
        gcd(b, a % b)
    }
}

fn now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// The machine's name, for telling apart processes of nodes that share
/// the bake directory.
fn host_name() -> String {
    fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "an unknown host".into())
}

/// The exclusive lock of a bake's serial steps; released when dropped.
#[derive(Debug)]
pub struct Setup {
    dir: PathBuf,
    file: File,
}

impl Setup {
    /// Locks `dir/.lock` (creating `dir`), waiting while another run holds
    /// it: its steps under the lock end (or it dies and the kernel frees
    /// the lock), so the wait ends; saying whom it waits for keeps it from
    /// looking like a hang.
    pub fn acquire(dir: &Path, me: &Holder) -> Result<Setup> {
        fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join(LOCK);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("opening the bake's lock {}", path.display()))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let holder = read_holder(&mut file)
                    .map_or_else(|| "another process".to_string(), |h| h.to_string());
                eprintln!(
                    "{}: waiting for {holder} to finish starting or checking the bake (its lock {})",
                    dir.display(),
                    path.display()
                );
                file.lock()
                    .with_context(|| format!("locking {}", path.display()))?;
            }
            Err(TryLockError::Error(e)) => {
                return Err(e).with_context(|| {
                    format!(
                        "locking {} (the filesystem must support file locks)",
                        path.display()
                    )
                })
            }
        }
        write_holder(&mut file, me).with_context(|| format!("writing {}", path.display()))?;
        Ok(Setup {
            dir: dir.to_path_buf(),
            file,
        })
    }

    /// A live run, if there is any; removes the files of dead runs it
    /// meets (nothing registers while the lock is held, so none is new).
    /// Stops at the first live one: with a thousand array tasks running,
    /// probing them all, in every task, would cost a million lock calls.
    pub fn anyone(&self) -> Option<Holder> {
        scan(&self.dir, true, |_| true, true).pop()
    }

    /// Registers `me` as rendering (or reading) its images, refusing when
    /// a live run has any of them; the registration lasts as long as the
    /// returned [`Running`]. Probes only the runs whose file names a
    /// shard that shares an image with `me`.
    pub fn register(&self, me: &Holder) -> Result<Running> {
        let mine = me.shard();
        let in_the_way = scan(
            &self.dir,
            true,
            |s| s.is_none_or(|s| overlap(s, mine)),
            true,
        );
        if let Some(h) = in_the_way.iter().find(|h| h.overlaps(me)) {
            let shards = if h.shard_count > 1 {
                format!(
                    "; only the other shards of its bake (--shard i/{}) may run beside it",
                    h.shard_count
                )
            } else {
                String::new()
            };
            bail!(
                "{} is in use by {h}, on images this run needs too: wait for it to end, or stop it (a stopped bake resumes){shards}",
                self.dir.display()
            );
        }
        let folder = self.dir.join(RUNNING);
        fs::create_dir_all(&folder).with_context(|| format!("creating {}", folder.display()))?;
        static SEQUENCE: AtomicU64 = AtomicU64::new(0);
        let path = folder.join(format!(
            "{}-of-{}.{}.{}.{}",
            mine.index,
            mine.count,
            me.host.replace(['/', '\\'], "_"),
            me.pid,
            SEQUENCE.fetch_add(1, Ordering::Relaxed)
        ));
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .with_context(|| format!("creating {}", path.display()))?;
        // Removed again if what follows fails (a full disk): a file no run
        // holds would only be cleaned up by a later run.
        let mut running = Running { path, file };
        running
            .file
            .try_lock()
            .map_err(|e| anyhow::anyhow!("{e}"))
            .with_context(|| format!("locking {}", running.path.display()))?;
        write_holder(&mut running.file, me)
            .with_context(|| format!("writing {}", running.path.display()))?;
        Ok(running)
    }

    /// Removes the temporary files that killed runs left in the bake (see
    /// [`manifest::is_temporary`]); call only when no other run is alive,
    /// as one that is may be writing them. Returns how many were removed.
    pub fn remove_temporaries(&self) -> Result<usize> {
        let mut removed = 0;
        for folder in [self.dir.clone(), self.dir.join(IMAGES)] {
            let Ok(entries) = folder.read_dir() else {
                continue;
            };
            for e in entries.flatten() {
                let is_file = e.file_type().is_ok_and(|t| t.is_file());
                if is_file && manifest::is_temporary(&e.file_name()) {
                    fs::remove_file(e.path()).with_context(|| {
                        format!("removing the temporary file {}", e.path().display())
                    })?;
                    removed += 1;
                }
            }
        }
        Ok(removed)
    }
}

impl Drop for Setup {
    fn drop(&mut self) {
        // A waiter reading the file after this must not name this run.
        let _ = self.file.set_len(0);
    }
}

/// A run's registration: its file, locked while the run lives; removed
/// when dropped (a killed run's is removed by the next one).
#[derive(Debug)]
pub struct Running {
    path: PathBuf,
    /// Locked for the run's life: a file no one holds is a dead run's.
    file: File,
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = fs::remove_file(&self.path);
    }
}

/// The runs alive in the bake in `dir` now, for a report: takes no lock
/// and removes nothing.
pub fn running(dir: &Path) -> Vec<Holder> {
    scan(dir, false, |_| true, false)
}

/// The shard a registration's file name (`<i>-of-<n>.<host>.<pid>.<k>`)
/// gives, if it gives one.
fn shard_of(name: &std::ffi::OsStr) -> Option<Shard> {
    let name = name.to_str()?;
    let (i, n) = name.split('.').next()?.split_once("-of-")?;
    let (index, count) = (i.parse().ok()?, n.parse().ok()?);
    (index < count).then_some(Shard { index, count })
}

/// The holders of the registrations whose names `wanted` admits (a name
/// without a shard is passed as `None`) that someone holds locked; with
/// `tidy`, removes the files of dead runs probed; with `first`, stops at
/// the first live one.
fn scan(
    dir: &Path,
    tidy: bool,
    wanted: impl Fn(Option<Shard>) -> bool,
    first: bool,
) -> Vec<Holder> {
    let Ok(entries) = dir.join(RUNNING).read_dir() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for e in entries.flatten() {
        if first && !out.is_empty() {
            break;
        }
        if !wanted(shard_of(&e.file_name())) {
            continue;
        }
        let path = e.path();
        let Ok(mut file) = File::open(&path) else {
            continue;
        };
        // Probes take the lock shared: two probes never mistake each
        // other for a live run; a run holds its file exclusively.
        match file.try_lock_shared() {
            Ok(()) => {
                drop(file);
                if tidy {
                    let _ = fs::remove_file(&path);
                }
            }
            Err(TryLockError::WouldBlock) => {
                out.push(read_holder(&mut file).unwrap_or_else(|| Holder {
                    pid: 0,
                    host: "an unknown host".into(),
                    command: path.display().to_string(),
                    what: "starting".into(),
                    shard_index: 0,
                    shard_count: 1,
                    started: now(),
                }))
            }
            Err(TryLockError::Error(_)) => {}
        }
    }
    out.sort_by_key(|h| (h.started, h.pid));
    out
}

fn read_holder(file: &mut File) -> Option<Holder> {
    let mut text = String::new();
    file.read_to_string(&mut text).ok()?;
    serde_json::from_str(&text).ok()
}

fn write_holder(file: &mut File, me: &Holder) -> std::io::Result<()> {
    file.set_len(0)?;
    let text = serde_json::to_string(me).map_err(std::io::Error::other)?;
    use std::io::Seek;
    file.seek(std::io::SeekFrom::Start(0))?;
    file.write_all(text.as_bytes())?;
    file.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn holder(index: u32, count: u32) -> Holder {
        Holder::me("baking", Shard { index, count })
    }

    #[test]
    fn a_registration_names_its_shard() {
        assert_eq!(
            shard_of("3-of-4.node7.12.0".as_ref()),
            Some(Shard { index: 3, count: 4 })
        );
        for bad in ["4-of-4.h.1.0", "junk", "x-of-2.h.1.0"] {
            assert_eq!(shard_of(bad.as_ref()), None, "{bad}");
        }
    }

    #[test]
    fn shards_overlap_exactly_when_they_share_an_image() {
        for (a, b) in [((0, 2), (1, 2)), ((0, 2), (1, 4)), ((1, 3), (2, 6))] {
            let (a, b) = (holder(a.0, a.1), holder(b.0, b.1));
            assert!(!a.overlaps(&b) && !b.overlaps(&a), "{a:?} {b:?}");
        }
        for (a, b) in [
            ((0, 1), (1, 2)),
            ((0, 2), (0, 2)),
            ((1, 2), (3, 4)),
            ((0, 3), (3, 6)),
        ] {
            let (a, b) = (holder(a.0, a.1), holder(b.0, b.1));
            assert!(a.overlaps(&b) && b.overlaps(&a), "{a:?} {b:?}");
        }
        // Against brute force.
        for n in 1..7 {
            for m in 1..7 {
                for i in 0..n {
                    for j in 0..m {
                        let shared = (0..n * m).any(|k| k % n == i && k % m == j);
                        assert_eq!(holder(i, n).overlaps(&holder(j, m)), shared);
                    }
                }
            }
        }
    }

    #[test]
    fn a_live_run_is_seen_and_refuses_overlapping_ones_and_a_dead_one_is_removed() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let setup = Setup::acquire(dir, &holder(0, 1)).unwrap();
        assert_eq!(setup.anyone(), None);
        let first = setup.register(&holder(0, 2)).unwrap();
        let others = running(dir);
        assert_eq!(others.len(), 1);
        assert_eq!(others[0].shard(), Shard { index: 0, count: 2 });
        assert_eq!(setup.anyone().as_ref(), Some(&others[0]));
        // The other shard shares the bake; the whole bake and the same shard
        // do not.
        let second = setup.register(&holder(1, 2)).unwrap();
        assert_eq!(running(dir).len(), 2);
        for (i, n) in [(0, 1), (0, 2), (2, 4), (3, 4)] {
            let err = setup.register(&holder(i, n)).unwrap_err();
            assert!(err.to_string().contains("(this process)"), "{err}");
        }
        drop((first, second));
        assert!(running(dir).is_empty());
        // Files nobody holds are dead runs': not counted, and removed when
        // probed under the lock.
        for name in ["0-of-1.elsewhere.1.0", "junk"] {
            fs::write(dir.join(RUNNING).join(name), "{}").unwrap();
        }
        assert!(running(dir).is_empty());
        assert!(dir.join(RUNNING).join("junk").exists());
        let third = setup.register(&holder(1, 2)).unwrap();
        assert_eq!(fs::read_dir(dir.join(RUNNING)).unwrap().count(), 1);
        drop(third);
    }
}
