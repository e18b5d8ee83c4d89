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

type Job = Box<dyn FnOnce() + Send>;

static WORKER: OnceLock<Mutex<Sender<Job>>> = OnceLock::new();

/// Where processes meet to take turns with Symbolica.
pub fn lock_path() -> PathBuf {
    std::env::temp_dir().join("sdnn-symbolica.lock")
}

/// Runs `work` on the Symbolica thread and returns its result.
pub fn run<T: Send + 'static>(work: impl FnOnce() -> T + Send + 'static) -> Result<T, String> {
    let sender = WORKER
        .get_or_init(|| Mutex::new(spawn_worker()))
        .lock()
        .map_err(|_| "the Symbolica thread's queue is poisoned by an earlier panic".to_string())?;
    let (reply, result) = channel();
    let job: Job = Box::new(move || {
        let _ = reply.send(work());
    });
    sender
        .send(job)
        .map_err(|_| "the Symbolica thread has stopped".to_string())?;
    drop(sender);
    result
        .recv()
        .map_err(|_| "the Symbolica job panicked; see the message above".to_string())
}

fn spawn_worker() -> Sender<Job> {
    let (sender, jobs) = channel::<Job>();
    std::thread::Builder::new()
        .name("symbolica".into())
        .spawn(move || {
            // Held until the process exits: Symbolica state lives as long as the thread.
            let _lock = acquire_lock();
            for job in jobs {
                job();
            }
        })
        .expect("cannot start the Symbolica thread");
    sender
}

fn acquire_lock() -> Option<File> {
    let path = lock_path();
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .ok()?;
    if file.try_lock().is_err() {
        eprintln!(
            "sdnn-codegen: waiting for another process to finish with Symbolica (lock {})",
            path.display()
        );
        file.lock().ok()?;
    }
    Some(file)
}
