//! The one writer of every output file.
//!
//! A file is written to an unpredictably named temporary file in its own
//! directory (the `tempfile` crate), synced, then renamed over the
//! destination, so a reader never sees half a file and a failure leaves the
//! old one. A symbolic link is followed (its target is replaced, the link
//! stays), the permissions of a replaced file are kept, and a read-only file
//! is refused, not replaced. In the `sdnn` command (`protect_inputs`, called
//! by `main`) the files read are noted as inputs (`note_input`) and writing
//! over one of them is refused: a command's outputs never destroy the data
//! they came from. `replace_input` is the one deliberate exception
//! (`diagnose --apply` edits the TOML it read). A library user, who may
//! well rewrite a file it read, is not restricted. The path `-` is standard
//! output (a file named `-` is `./-`). A folder of outputs is written
//! whole through [`StagedFolder`].

use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

mod folder;

pub use folder::StagedFolder;

/// Canonical paths of the files this process has read.
static INPUTS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Temporary files and staged folders being written (not yet in place).
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Whether outputs over inputs are refused (the `sdnn` command).
static PROTECT: AtomicBool = AtomicBool::new(false);

/// From now on, no output of this process may replace a file it read.
pub fn protect_inputs() {
    PROTECT.store(true, Ordering::Relaxed);
}

/// Notes that this process reads `path` (see `protect_inputs`).
pub fn note_input(path: &Path) {
    if !PROTECT.load(Ordering::Relaxed) {
        return;
    }
    if let Ok(canonical) = fs::canonicalize(path) {
        let mut inputs = INPUTS.lock().unwrap_or_else(|e| e.into_inner());
        if !inputs.contains(&canonical) {
            inputs.push(canonical);
        }
    }
}

/// Removes the temporary files of writes in progress: what the `sdnn`
/// binary does on an interrupt (Ctrl-C, SIGTERM) before it exits, so no
/// `.sdnn-XXXX.tmp` is left beside the outputs. A finished write is
/// complete and stays.
pub fn remove_pending() {
    // A staged folder's files moving into place finish first (see `folder`).
    let _moving = folder::COMMIT.lock().unwrap_or_else(|e| e.into_inner());
    let pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
    for path in pending.iter() {
        if path.is_dir() {
            // Other threads may still be writing into it: a few attempts.
            for _ in 0..3 {
                if fs::remove_dir_all(path).is_ok() || !path.exists() {
                    break;
                }
            }
        } else {
            let _ = fs::remove_file(path);
        }
    }
}

/// Notes a temporary file while it is written; unnoted when dropped.
struct Pending(PathBuf);

impl Pending {
    fn new(path: &Path) -> Pending {
        let mut pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
        pending.push(path.to_path_buf());
        Pending(path.to_path_buf())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        let mut pending = PENDING.lock().unwrap_or_else(|e| e.into_inner());
        pending.retain(|p| p != &self.0);
    }
}

/// Whether `path` means standard output.
pub fn is_stdout(path: &Path) -> bool {
    path == Path::new("-")
}

/// Prints `text` on standard output and flushes it. A failed write (a
/// full disk, a closed descriptor) is an error the command returns, where
/// `print!` would panic; a closed pipe stays quiet (`main`).
pub fn print(text: &str) -> io::Result<()> {
    let mut out = io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| io::Error::new(e.kind(), format!("writing to standard output: {e}")))
}

/// [`print`] with a line end.
pub fn print_line(text: &str) -> io::Result<()> {
    print(&format!("{text}\n"))
}

/// Writes a line on standard error, ignoring a failed write: what the
/// `say!` macro does for every progress note, warning and error message.
/// Those lines are for a human; when standard error is closed or on a
/// full device (`2>/dev/full`) they are lost, and the command still does
/// its work and exits with its own code, where `eprintln!` would panic
/// (exit 101).
pub fn say_line(text: std::fmt::Arguments) {
    let mut err = io::stderr().lock();
    let _ = err.write_fmt(text).and_then(|()| err.write_all(b"\n"));
}

/// `eprintln!` that never panics: a line on standard error, a failed write
/// ignored (see [`say_line`]).
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::output::say_line(format_args!($($arg)*))
    };
}

/// Creates the output folder `path` (and its parents). `-` is refused: a
/// folder of files cannot go to standard output.
pub fn create_folder(path: &Path) -> io::Result<()> {
    if is_stdout(path) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "`-` (standard output) cannot hold a folder of files; give a folder path",
        ));
    }
    fs::create_dir_all(path)
}

/// Writes `bytes` to `path` (see the module documentation).
pub fn write(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_with(path, |w| w.write_all(bytes))
}

/// Writes what `body` produces to `path` (see the module documentation).
pub fn write_with(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    if is_stdout(path) {
        let mut w = BufWriter::new(io::stdout().lock());
        body(&mut w)?;
        return w.flush();
    }
    let target = destination(path)?;
    if is_input(&target) {
        return Err(io::Error::new(
            io::ErrorKind::AlreadyExists,
            "this command reads that file; refusing to write its output over it \
             (choose another output path)",
        ));
    }
    if is_special(&target) {
        // A device or a FIFO (/dev/null, a pipe to another program) is
        // written into, never replaced by a regular file.
        let mut w = BufWriter::new(fs::OpenOptions::new().write(true).open(&target)?);
        body(&mut w)?;
        return w.flush();
    }
    replace(&target, body)
}

/// Whether `path` exists and is neither a regular file nor a directory.
fn is_special(path: &Path) -> bool {
    fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Replaces an input file on purpose (an edit of the file read), with the
/// same guarantees otherwise.
pub fn replace_input(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let target = destination(path)?;
    replace(&target, |w| w.write_all(bytes))
}

/// The file to write: the target of a symbolic link, else `path`.
fn destination(path: &Path) -> io::Result<PathBuf> {
    if path.file_name().is_none() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a file path (it has no file name)",
        ));
    }
    match fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => fs::canonicalize(path),
        Ok(meta) if meta.is_dir() => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is a directory; give a file path",
        )),
        _ => Ok(path.to_path_buf()),
    }
}

fn is_input(target: &Path) -> bool {
    let Ok(canonical) = fs::canonicalize(target) else {
        return false; // does not exist yet
    };
    let inputs = INPUTS.lock().unwrap_or_else(|e| e.into_inner());
    inputs.contains(&canonical)
}

fn replace(target: &Path, body: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> io::Result<()> {
    let existing = fs::metadata(target).ok();
    if existing
        .as_ref()
        .is_some_and(|m| m.permissions().readonly())
    {
        return Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            "is read-only; not replaced (make it writable or choose another path)",
        ));
    }
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!("the folder {} does not exist", dir.display()),
        ));
    }
    let mut temporary = tempfile::Builder::new()
        .prefix(".sdnn-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    let _pending = Pending::new(temporary.path());
    {
        let mut w = BufWriter::new(temporary.as_file_mut());
        body(&mut w)?;
        w.flush()?;
    }
    temporary.as_file().sync_all()?;
    // A new file is readable by all like any file a tool writes (the
    // temporary file is private until it is complete).
    let permissions = existing.map_or_else(
        || std::os::unix::fs::PermissionsExt::from_mode(0o644),
        |meta| meta.permissions(),
    );
    fs::set_permissions(temporary.path(), permissions)?;
    temporary.persist(target).map_err(|e| e.error)?;
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::os::unix::fs::FileTypeExt;

    /// Tests that call `remove_pending` (which removes every pending file
    /// of the process) or keep a folder pending run one at a time.
    pub(crate) static SERIAL: Mutex<()> = Mutex::new(());

    #[test]
    fn writes_and_replaces_without_leftovers() {
        // An interrupt test's `remove_pending` beside it removed this
        // write's temporary file once (CI, 2026-11-27).
        let _serial = SERIAL.lock();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        write(&path, b"one").unwrap();
        write(&path, b"two").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "two");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn an_interrupt_removes_the_temporary_file_of_a_write_in_progress() {
        let _serial = SERIAL.lock();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        let temporaries = || {
            fs::read_dir(dir.path())
                .unwrap()
                .filter_map(|e| e.ok()?.file_name().into_string().ok())
                .filter(|name| name.starts_with(".sdnn-"))
                .count()
        };
        let result = write_with(&path, |w| {
            w.write_all(b"half")?;
            assert_eq!(
                temporaries(),
                1,
                "the write in progress has its temporary file"
            );
            // What the binary's interrupt handler calls.
            remove_pending();
            assert_eq!(temporaries(), 0);
            Ok(())
        });
        // The interrupted write cannot complete; a later write still works.
        assert!(result.is_err());
        assert!(!path.exists());
        write(&path, b"whole").unwrap();
        remove_pending();
        assert_eq!(fs::read_to_string(&path).unwrap(), "whole");
        assert_eq!(temporaries(), 0);
    }

    #[cfg(unix)]
    #[test]
    fn links_are_followed_and_permissions_kept() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.toml");
        fs::write(&real, "a").unwrap();
        fs::set_permissions(&real, fs::Permissions::from_mode(0o640)).unwrap();
        let link = dir.path().join("link.toml");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write(&link, b"b").unwrap();
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read_to_string(&real).unwrap(), "b");
        let mode = fs::metadata(&real).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o640);
        fs::set_permissions(&real, fs::Permissions::from_mode(0o444)).unwrap();
        let error = write(&real, b"c").unwrap_err();
        assert!(error.to_string().contains("read-only"), "{error}");
        assert_eq!(fs::read_to_string(&real).unwrap(), "b");
    }

    #[test]
    fn devices_and_fifos_are_written_into_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || fs::read_to_string(fifo).unwrap())
        };
        write(&fifo, b"through the pipe").unwrap();
        assert_eq!(reader.join().unwrap(), "through the pipe");
        assert!(fs::metadata(&fifo).unwrap().file_type().is_fifo());
        write(Path::new("/dev/null"), b"nothing").unwrap();
        assert!(
            fs::metadata("/dev/null")
                .unwrap()
                .file_type()
                .is_char_device()
        );
    }

    #[test]
    fn a_directory_or_a_missing_folder_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(write(dir.path(), b"x").is_err());
        assert!(write(&dir.path().join("no/such/dir/out.txt"), b"x").is_err());
        assert!(write(Path::new("/"), b"x").is_err());
    }
}
