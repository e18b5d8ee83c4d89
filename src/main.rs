//! The `sdnn` command line: `main` only maps the outcome to an exit code.

use std::process::ExitCode;

fn main() -> ExitCode {
    restore_sigpipe();
    sdnn::install_models();
    sdnn::output::protect_inputs();
    match sdnn::cli::run(std::env::args_os()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            if is_broken_pipe(&error) {
                return ExitCode::SUCCESS;
            }
            eprintln!("sdnn: {}", sdnn::errors::message(&error));
            ExitCode::from(2)
        }
    }
}

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
