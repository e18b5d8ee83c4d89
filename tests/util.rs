//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sdnn::oracle::Model;

/// The crate root (where `models/` lives).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The oracle model of `models/<name>.toml`.
pub fn oracle(name: &str) -> Model {
    let path = root().join("models").join(format!("{name}.toml"));
    let description = codegen::Description::load(&path).unwrap_or_else(|e| panic!("{e}"));
    Model::from_description(&description)
}

/// A random joint state: q in [-pi, pi], qd in [-3, 3], qdd in [-10, 10].
pub struct States {
    rng: ChaCha8Rng,
    dof: usize,
}

impl States {
    pub fn new(dof: usize, seed: u64) -> States {
        States {
            rng: ChaCha8Rng::seed_from_u64(seed),
            dof,
        }
    }

    pub fn next(&mut self) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut draw = |limit: f64| -> Vec<f64> {
            (0..self.dof)
                .map(|_| self.rng.random_range(-limit..limit))
                .collect()
        };
        let q = draw(std::f64::consts::PI);
        let qd = draw(3.0);
        let qdd = draw(10.0);
        (q, qd, qdd)
    }
}

/// Asserts |a - b| <= 1e-9 |b| or <= 1e-12, with a message naming `what`.
#[track_caller]
pub fn assert_close(a: f64, b: f64, what: &str) {
    let ok = (a - b).abs() <= 1e-9 * b.abs() || (a - b).abs() <= 1e-12;
    assert!(ok, "{what}: {a} vs {b} (difference {:e})", a - b);
}

/// A scratch directory removed when dropped.
pub struct Dir(tempfile::TempDir);

impl Dir {
    pub fn new() -> Dir {
        Dir(tempfile::tempdir().expect("temporary directory"))
    }

    pub fn path(&self) -> &Path {
        self.0.path()
    }

    pub fn write(&self, name: &str, contents: &str) -> PathBuf {
        let path = self.0.path().join(name);
        std::fs::write(&path, contents).expect("write test file");
        path
    }

    /// Each recording as a CSV file `{stem}{k}.csv`, the paths as `--data`
    /// takes them.
    pub fn recordings(
        &self,
        stem: &str,
        recordings: impl IntoIterator<Item = sdnn::trajectory::Trajectory>,
    ) -> Vec<String> {
        recordings
            .into_iter()
            .enumerate()
            .map(|(k, r)| {
                let path = self.0.path().join(format!("{stem}{k}.csv"));
                sdnn::trajectory::write_csv(&path, &r).expect("write recording");
                path.to_str().expect("a UTF-8 path").to_string()
            })
            .collect()
    }
}

/// Runs the `sdnn` binary.
pub fn sdnn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sdnn"))
        .args(args)
        .output()
        .expect("run sdnn")
}

/// `count` recordings of `seconds` each on the default virtual robot, in
/// `dir/rec` (`sdnn simulate`, which must succeed).
pub fn simulated_recordings(dir: &Dir, count: usize, seconds: f64) -> Vec<PathBuf> {
    let out = dir.path().join("rec");
    let (count_text, seconds_text) = (count.to_string(), seconds.to_string());
    let run = sdnn(&[
        "simulate",
        "--count",
        &count_text,
        "--duration",
        &seconds_text,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    (1..=count)
        .map(|k| out.join(format!("trajectory_{k:02}.csv")))
        .collect()
}

/// Runs the `sdnn` binary, which must succeed, and parses its JSON output.
pub fn sdnn_json(args: &[&str]) -> serde_json::Value {
    let run = sdnn(args);
    assert!(
        run.status.success(),
        "sdnn {args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    serde_json::from_slice(&run.stdout).expect("JSON output")
}

/// Reference data the repository does not carry (the Franka Panda log of
/// Gaz et al. 2019 is GPL-3.0; see docs/verification.md for where to get
/// it): `<relative>` under `$SDNN_REFERENCE_DIR` (relative to the crate
/// root), by default `../shared/reference` beside the repository. Without
/// `SDNN_REFERENCE_DIR` and without the data, `None`: the caller skips, and
/// a line on the test run's stderr (past the harness's capture) says what
/// is skipped and how to get the data. A `SDNN_REFERENCE_DIR` that lacks
/// the data is an error, so a mistyped path never passes silently.
pub fn reference_data(relative: &str, skipped: &str) -> Option<PathBuf> {
    use std::io::Write;
    let set = std::env::var_os("SDNN_REFERENCE_DIR");
    let dir = root().join(set.as_deref().unwrap_or("../shared/reference".as_ref()));
    let path = dir.join(relative);
    if path.exists() {
        return Some(path);
    }
    assert!(
        set.is_none(),
        "SDNN_REFERENCE_DIR={}: no {relative} there (docs/verification.md says how to get it)",
        dir.display()
    );
    // Written to the process's stderr, not through eprintln!, which the test
    // harness captures and shows only for failing tests.
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED {skipped}: no {relative} in ../shared/reference beside the \
         repository; put the data there or set SDNN_REFERENCE_DIR to where it \
         is (docs/verification.md, \"Reference data\", says how to get it)"
    );
    None
}
