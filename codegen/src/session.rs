//! The one Symbolica thread of this process.
//!
//! Without a licence key Symbolica allows one thread per user at a time: a
//! second thread in the process, or a second process, aborts. So every
//! Symbolica call runs on one dedicated worker thread, started on first use
//! and kept for the life of the process, and that thread first takes an
//! exclusive lock on a file shared by all processes of this user.

use std::fs::File;
use std::path::PathBuf;
use std::sync::mpsc::{Sender, channel};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

/// A job gets the lock's failure, if any, instead of running Symbolica.
type Job = Box<dyn FnOnce(Option<&str>) + Send>;

static WORKER: OnceLock<Mutex<Sender<Job>>> = OnceLock::new();

/// Longest wait for another process's Symbolica work.
const WAIT: Duration = Duration::from_secs(600);

/// Where processes meet to take turns with Symbolica: one file per user,
/// in the home directory's cache (not `$TMPDIR`, which differs between
/// builds), or `/tmp` without a home directory.
pub fn lock_path() -> PathBuf {
    let user = std::env::var("USER")
        .or_else(|_| std::env::var("USERNAME"))
        .unwrap_or_else(|_| "user".into());
    match std::env::var_os("HOME").filter(|h| !h.is_empty()) {
        Some(home) => PathBuf::from(home).join(".cache/sdnn/symbolica.lock"),
        None => std::env::temp_dir().join(format!("sdnn-symbolica-{user}.lock")),
    }
}

/// Runs `work` on the Symbolica thread and returns its result.
pub fn run<T: Send + 'static>(work: impl FnOnce() -> T + Send + 'static) -> Result<T, String> {
    let sender = WORKER
        .get_or_init(|| Mutex::new(spawn_worker()))
        .lock()
        .map_err(|_| "the Symbolica thread's queue is poisoned by an earlier panic".to_string())?;
    let (reply, result) = channel();
    let job: Job = Box::new(move |lock_error| {
        let _ = reply.send(match lock_error {
            Some(error) => Err(error.to_string()),
            None => Ok(work()),
        });
    });
    sender
        .send(job)
        .map_err(|_| "the Symbolica thread has stopped".to_string())?;
    drop(sender);
    result
        .recv()
        .map_err(|_| "the Symbolica job panicked; see the message above".to_string())?
}

fn spawn_worker() -> Sender<Job> {
    let (sender, jobs) = channel::<Job>();
    std::thread::Builder::new()
        .name("symbolica".into())
        .spawn(move || {
            // Held until the process exits: Symbolica state lives as long as the thread.
            let lock = acquire_lock();
            let error = lock.as_ref().err().map(String::as_str);
            for job in jobs {
                job(error);
            }
        })
        .expect("cannot start the Symbolica thread");
    sender
}

/// Takes the cross-process lock, waiting up to `WAIT`; every failure is
/// an error that names the lock file.
fn acquire_lock() -> Result<File, String> {
    let path = lock_path();
    let fail = |what: &str, e: &dyn std::fmt::Display| {
        format!("Symbolica lock {}: {what}: {e}", path.display())
    };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| fail("cannot create its folder", &e))?;
    }
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| fail("cannot open", &e))?;
    let start = Instant::now();
    let mut said = false;
    loop {
        match file.try_lock() {
            Ok(()) => return Ok(file),
            Err(std::fs::TryLockError::WouldBlock) => {}
            Err(std::fs::TryLockError::Error(e)) => return Err(fail("cannot lock", &e)),
        }
        if start.elapsed() > WAIT {
            return Err(fail(
                "another process has held it for 10 minutes",
                &"stop it or remove a stale lock holder, then rebuild",
            ));
        }
        if !said {
            eprintln!(
                "sdnn-codegen: waiting for another process to finish with Symbolica (lock {})",
                path.display()
            );
            said = true;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}
