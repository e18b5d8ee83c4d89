//! The `sdnn` command line: `main` only maps the outcome to an exit code.

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

// mimalloc keeps freed pages for the next allocation: the diagnosis builds
// and drops full-rate columns of megabytes, and the system allocator
// returned each to the kernel, so every new one paid its page faults again
// (a sixth of a 3-DOF diagnosis's time; docs/diagnosis-measured.md, Speed).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    restore_sigpipe();
    remove_temporaries_on_interrupt();
    sdnn::install_models();
    sdnn::output::protect_inputs();
    let outcome = sdnn::cli::run(std::env::args_os());
    if INTERRUPTED.load(Ordering::SeqCst) {
        // The handler is removing what this thread was writing (the cause
        // of its error, if any): it finishes and exits 130 itself.
        loop {
            std::thread::park();
        }
    }
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            if is_broken_pipe(&error) {
                return ExitCode::SUCCESS;
            }
            sdnn::say!("sdnn: {}", sdnn::errors::message(&error));
            ExitCode::from(sdnn::errors::exit_code(&error))
        }
    }
}

/// On Ctrl-C or SIGTERM, the temporary files of writes in progress are
/// removed before the process ends (exit code 130): an interrupted command
/// leaves its finished outputs and no `.sdnn-XXXX.tmp` beside them.
fn remove_temporaries_on_interrupt() {
    // Without a handler (another one already installed) the default
    // action stays; nothing else depends on it.
    let _ = ctrlc::set_handler(|| {
        INTERRUPTED.store(true, Ordering::SeqCst);
        sdnn::output::remove_pending();
        std::process::exit(130);
    });
}

/// Set by the interrupt handler before it removes anything.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

fn is_broken_pipe(error: &anyhow::Error) -> bool {
    error
        .chain()
        .filter_map(|e| e.downcast_ref::<std::io::Error>())
        .any(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
}

/// Rust ignores SIGPIPE, so printing into a closed pipe (`sdnn ... | head`)
/// would panic in `println!`; the default action ends the process quietly,
/// as other Unix tools do.
fn restore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called first in main, before any thread exists; SIG_DFL is a
    // valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
