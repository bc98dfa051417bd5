//! Output files that appear whole or not at all.
//!
//! Every file dampscope writes goes first to a hidden temporary name in the target directory
//! (`.NAME.partial-PID-N.EXT`, same file system, same extension so that writers choosing a
//! format by extension — the PNG encoder — still do) and is renamed over the final name once it
//! is complete. `rename` within a directory is atomic on POSIX file systems: a reader sees the
//! old file or the new one, never half of it. A run that is killed leaves at most a hidden
//! `.partial` file, never a half-written file under a name that looks like a result; one that
//! fails cleanly removes its temporary file (dropping an uncommitted [`AtomicFile`] does).

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Marker in temporary names: `dampscope` never reads a file whose name contains it.
pub const PARTIAL_MARKER: &str = ".partial-";

/// A temporary path beside `target`, unique within the process.
pub fn temporary_path(target: &Path) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = target
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let (stem, ext) = match name.rsplit_once('.') {
        Some((s, e)) if !s.is_empty() => (s.to_string(), format!(".{e}")),
        _ => (name.clone(), String::new()),
    };
    let pid = std::process::id();
    let temp = format!(".{stem}{PARTIAL_MARKER}{pid}-{n}{ext}");
    match target.parent() {
        Some(dir) => dir.join(temp),
        None => PathBuf::from(temp),
    }
}

/// A path to write to by name (for writers that open the file themselves, like the figure
/// backends), renamed to its target by [`StagedPath::commit`]; removed when dropped uncommitted.
#[derive(Debug)]
pub struct StagedPath {
    temp: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl StagedPath {
    /// A staged path for `target`. Nothing is created yet.
    pub fn new(target: &Path) -> Self {
        StagedPath {
            temp: temporary_path(target),
            target: target.to_path_buf(),
            committed: false,
        }
    }

    /// Where to write.
    pub fn path(&self) -> &Path {
        &self.temp
    }

    /// The final name.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Renames the written file to its final name (replacing any old file there).
    pub fn commit(mut self) -> io::Result<()> {
        std::fs::rename(&self.temp, &self.target).map_err(|e| {
            io::Error::new(
                e.kind(),
                format!(
                    "cannot rename {} to {}: {e}",
                    self.temp.display(),
                    self.target.display()
                ),
            )
        })?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedPath {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// A buffered file under a temporary name, renamed to its final name by [`AtomicFile::commit`].
/// Dropped without a commit (an error on the way), it deletes itself.
pub struct AtomicFile {
    out: BufWriter<File>,
    staged: StagedPath,
}

impl AtomicFile {
    /// Creates the temporary file for `target`.
    pub fn create(target: &Path) -> io::Result<Self> {
        let staged = StagedPath::new(target);
        let file = File::create(staged.path()).map_err(|e| {
            io::Error::new(e.kind(), format!("cannot create {}: {e}", target.display()))
        })?;
        Ok(AtomicFile {
            out: BufWriter::new(file),
            staged,
        })
    }

    /// Flushes, syncs the data to disk and renames the file to its final name.
    pub fn commit(self) -> io::Result<()> {
        let AtomicFile { out, staged } = self;
        let file = out.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        staged.commit()
    }

    /// The final name.
    pub fn target(&self) -> &Path {
        self.staged.target()
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.out.write(buf)
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.out.write_all(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// Writes `target` through `write` into an [`AtomicFile`]: the file appears complete or not at
/// all. Errors name the file.
pub fn write_file(
    target: &Path,
    write: impl FnOnce(&mut AtomicFile) -> io::Result<()>,
) -> io::Result<()> {
    let named = |e: io::Error| {
        if e.to_string().contains(&*target.to_string_lossy()) {
            e
        } else {
            io::Error::new(e.kind(), format!("{}: {e}", target.display()))
        }
    };
    let mut f = AtomicFile::create(target)?;
    write(&mut f).map_err(named)?;
    f.commit().map_err(named)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch_dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("dampscope-atomic-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn the_file_has_its_final_name_only_once_complete() {
        let dir = scratch_dir("commit");
        let target = dir.join("table.csv");
        let mut f = AtomicFile::create(&target).unwrap();
        f.write_all(b"a,b\n1,2\n").unwrap();
        f.flush().unwrap();
        assert!(!target.exists(), "final name before the commit");
        let listed = names(&dir);
        assert_eq!(listed.len(), 1);
        assert!(listed[0].starts_with(".table.partial-") && listed[0].ends_with(".csv"));
        f.commit().unwrap();
        assert_eq!(names(&dir), vec!["table.csv".to_string()]);
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "a,b\n1,2\n");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = scratch_dir("fail");
        let target = dir.join("global.csv");
        std::fs::write(&target, "old").unwrap();
        let err = write_file(&target, |w| {
            w.write_all(b"half")?;
            Err(io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("global.csv"), "{err}");
        assert_eq!(names(&dir), vec!["global.csv".to_string()]);
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
        write_file(&target, |w| w.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn temporary_names_keep_the_extension_and_differ() {
        let a = temporary_path(Path::new("out/map.png"));
        let b = temporary_path(Path::new("out/map.png"));
        assert_ne!(a, b);
        assert_eq!(a.extension().unwrap(), "png");
        assert_eq!(a.parent().unwrap(), Path::new("out"));
        let c = temporary_path(Path::new("README"));
        assert!(c.to_string_lossy().starts_with(".README.partial-"));
    }
}
