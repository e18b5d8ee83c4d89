//! A folder of outputs written whole, or the earlier one left whole.
//!
//! A command that writes many files into a folder (`reproduce`, `study`,
//! `simulate`) writes them into a temporary folder inside it
//! (`.sdnn-XXXX.tmp`), then moves them into place at the end (`commit`).
//! Interrupted or failed before that, the earlier run's files are untouched
//! and the temporary folder is removed (an interrupt waits for a move in
//! progress to finish), so new recordings never sit beside old results.
//!
//! Files the command does not write are never touched: a user may keep a
//! recording in the folder and read it (`study --data DIR/x.csv --out DIR`).
//! To remove what an earlier run wrote and this one does not (recordings
//! beyond a smaller count, networks of other settings), a run of a kind
//! (a command) records the files it wrote in the folder
//! (`.written_by_sdnn_KIND`), and the next run of that kind removes only
//! files listed there, and none it reads.

use std::fs;
use std::io;
use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

use super::{Pending, destination, is_input, is_special, replace};

/// Held while a staged folder's files move into place: the interrupt
/// handler (`remove_pending`) waits for it, so a move is never cut halfway.
pub(super) static COMMIT: Mutex<()> = Mutex::new(());

/// A folder being written: write into [`StagedFolder::path`], then
/// [`StagedFolder::commit`]. Dropped without a commit, it removes what was
/// written and leaves the folder as it was.
pub struct StagedFolder {
    target: PathBuf,
    kind: Option<&'static str>,
    // Declared before `stage`: unnoted as pending before the folder goes.
    _pending: Pending,
    stage: tempfile::TempDir,
}

impl StagedFolder {
    /// Starts writing the folder `target` (created if missing). `kind`
    /// names the command whose earlier files a commit may remove (see the
    /// module documentation); `None` removes nothing.
    pub fn begin(target: &Path, kind: Option<&'static str>) -> io::Result<StagedFolder> {
        super::create_folder(target)?;
        let stage = tempfile::Builder::new()
            .prefix(".sdnn-")
            .suffix(".tmp")
            .tempdir_in(target)?;
        Ok(StagedFolder {
            target: target.to_path_buf(),
            kind,
            _pending: Pending::new(stage.path()),
            stage,
        })
    }

    /// Where the command writes its files (paths relative to it are the
    /// files' paths in the folder).
    pub fn path(&self) -> &Path {
        self.stage.path()
    }

    /// Moves every file written into the folder, each replacing the file of
    /// the same name with the guarantees of `output::write` (an input or a
    /// read-only file is refused before anything moves, a symbolic link is
    /// followed, permissions are kept), then removes the files of the
    /// earlier run of the same kind that this one did not write. Returns
    /// those, relative to the folder.
    pub fn commit(self) -> io::Result<Vec<PathBuf>> {
        let mut written = files_below(self.path())?;
        let record = self.kind.map(record_name);
        if let Some(record) = &record {
            let text = record_text(&written);
            fs::write(self.path().join(record), text)?;
            written.push(PathBuf::from(record));
        }
        let _moving = COMMIT.lock().unwrap_or_else(|e| e.into_inner());
        for relative in &written {
            check_destination(&self.target.join(relative))?;
        }
        let earlier = match &record {
            Some(record) => read_record(&self.target.join(record)),
            None => Vec::new(),
        };
        for relative in &written {
            move_into(&self.path().join(relative), &self.target.join(relative))?;
        }
        let stale: Vec<PathBuf> = earlier
            .into_iter()
            .filter(|p| !written.contains(p))
            .collect();
        Ok(remove_files(&self.target, &stale))
    }
}

fn record_name(kind: &str) -> String {
    format!(".written_by_sdnn_{kind}")
}

fn record_text(files: &[PathBuf]) -> String {
    let mut text = String::from(
        "# The files sdnn wrote here in its last run of this kind, which the next run\n\
         # replaces (removing those it does not write again); other files are left alone.\n",
    );
    for file in files {
        text.push_str(&file.to_string_lossy());
        text.push('\n');
    }
    text
}

/// The files an earlier run recorded: plain relative paths only, so an
/// edited record can never name a file outside the folder.
fn read_record(path: &Path) -> Vec<PathBuf> {
    let Ok(text) = fs::read_to_string(path) else {
        return Vec::new();
    };
    text.lines()
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .map(PathBuf::from)
        .filter(|p| p.components().all(|c| matches!(c, Component::Normal(_))))
        .collect()
}

/// Every regular file below `root`, relative to it, sorted.
fn files_below(root: &Path) -> io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let mut folders = vec![PathBuf::new()];
    while let Some(folder) = folders.pop() {
        for entry in fs::read_dir(root.join(&folder))? {
            let entry = entry?;
            let relative = folder.join(entry.file_name());
            if entry.file_type()?.is_dir() {
                folders.push(relative);
            } else {
                files.push(relative);
            }
        }
    }
    files.sort();
    Ok(files)
}

/// Refuses a destination `output::write` would refuse, before any file moves.
fn check_destination(path: &Path) -> io::Result<()> {
    let named = |e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let target = destination(path).map_err(named)?;
    if is_input(&target) {
        return Err(named(io::Error::new(
            io::ErrorKind::AlreadyExists,
            "this command reads that file; refusing to write its output over it \
             (choose another output folder)",
        )));
    }
    if fs::metadata(&target).is_ok_and(|m| m.permissions().readonly()) {
        return Err(named(io::Error::new(
            io::ErrorKind::PermissionDenied,
            "is read-only; not replaced (make it writable or choose another folder)",
        )));
    }
    Ok(())
}

/// Puts the staged file `from` at `path`: a rename, or a copy where a
/// rename cannot go (a device, a link to another file system).
fn move_into(from: &Path, path: &Path) -> io::Result<()> {
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent)?;
    }
    let target = destination(path)?;
    let copy = |w: &mut dyn io::Write| io::copy(&mut fs::File::open(from)?, w).map(|_| ());
    if is_special(&target) {
        return copy(&mut fs::OpenOptions::new().write(true).open(&target)?);
    }
    if let Ok(meta) = fs::metadata(&target) {
        fs::set_permissions(from, meta.permissions())?;
    }
    match fs::rename(from, &target) {
        Err(e) if e.kind() == io::ErrorKind::CrossesDevices => replace(&target, copy),
        moved => moved,
    }
}

/// Removes the regular files `stale` below `root` (a link, a folder or a
/// file this process read of that name is left), then their folders if
/// that left them empty.
fn remove_files(root: &Path, stale: &[PathBuf]) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    for relative in stale {
        let path = root.join(relative);
        let is_file = fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_file());
        if is_file && !is_input(&path) && fs::remove_file(&path).is_ok() {
            removed.push(relative.clone());
        }
    }
    let mut folders: Vec<&Path> = removed
        .iter()
        .flat_map(|p| p.ancestors().skip(1))
        .filter(|p| !p.as_os_str().is_empty())
        .collect();
    // Deepest first; `remove_dir` leaves a folder that still holds anything.
    folders.sort_by_key(|p| std::cmp::Reverse(p.components().count()));
    folders.dedup();
    for folder in folders {
        let _ = fs::remove_dir(root.join(folder));
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(root: &Path, relative: &str, text: &str) {
        let path = root.join(relative);
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(path, text).unwrap();
    }

    fn read(root: &Path, relative: &str) -> String {
        fs::read_to_string(root.join(relative)).unwrap()
    }

    /// The earlier run's files stay whole until the commit, a run's own
    /// stale files go, and a user's files stay, whatever their names.
    #[test]
    fn replaces_a_run_whole_and_leaves_other_files() {
        let _serial = super::super::tests::SERIAL.lock();
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        let first = StagedFolder::begin(root, Some("test")).unwrap();
        write(first.path(), "results.md", "one");
        write(first.path(), "data/trajectory_01.csv", "one");
        write(first.path(), "data/trajectory_02.csv", "one");
        write(first.path(), "old/only.txt", "one");
        assert!(first.commit().unwrap().is_empty());
        write(root, "mine.csv", "user");
        write(root, "data/mine.csv", "user");

        let second = StagedFolder::begin(root, Some("test")).unwrap();
        write(second.path(), "results.md", "two");
        write(second.path(), "data/trajectory_01.csv", "two");
        assert_eq!(
            read(root, "results.md"),
            "one",
            "untouched until the commit"
        );
        let removed = second.commit().unwrap();
        assert_eq!(
            removed,
            [
                PathBuf::from("data/trajectory_02.csv"),
                PathBuf::from("old/only.txt")
            ]
        );
        assert_eq!(read(root, "results.md"), "two");
        assert_eq!(read(root, "data/trajectory_01.csv"), "two");
        assert_eq!(read(root, "mine.csv"), "user");
        assert_eq!(read(root, "data/mine.csv"), "user");
        assert!(!root.join("old").exists(), "a folder left empty goes");
        let names: Vec<String> = fs::read_dir(root)
            .unwrap()
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .collect();
        assert!(!names.iter().any(|n| n.starts_with(".sdnn-")), "{names:?}");
    }

    /// Dropped without a commit (an error, an interrupt), nothing changes.
    #[test]
    fn an_abandoned_run_leaves_the_folder_as_it_was() {
        let _serial = super::super::tests::SERIAL.lock();
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "results.md", "one");
        let staged = StagedFolder::begin(dir.path(), Some("test")).unwrap();
        write(staged.path(), "results.md", "two");
        let stage = staged.path().to_path_buf();
        drop(staged);
        assert!(!stage.exists());
        assert_eq!(read(dir.path(), "results.md"), "one");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// An edited record cannot make a commit remove anything outside the
    /// folder, nor a folder or a link inside it.
    #[test]
    fn a_record_names_only_plain_files_inside_the_folder() {
        let _serial = super::super::tests::SERIAL.lock();
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("out");
        write(dir.path(), "outside.txt", "keep");
        write(&root, "sub/kept.txt", "keep");
        std::os::unix::fs::symlink(dir.path().join("outside.txt"), root.join("link")).unwrap();
        write(
            &root,
            ".written_by_sdnn_test",
            "../outside.txt\n/etc/hostname\nsub\nlink\n",
        );
        let staged = StagedFolder::begin(&root, Some("test")).unwrap();
        write(staged.path(), "new.txt", "new");
        assert!(staged.commit().unwrap().is_empty());
        assert_eq!(read(dir.path(), "outside.txt"), "keep");
        assert_eq!(read(&root, "sub/kept.txt"), "keep");
        assert!(root.join("link").exists());
    }
}
