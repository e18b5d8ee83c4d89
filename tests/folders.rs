//! Folders of outputs (issue 26): `reproduce`, `study` and `simulate`
//! replace an earlier run whole, interrupted or not, and never touch the
//! files they did not write.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::util::{Dir, sdnn};

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Every file below `root` with its bytes, by path relative to `root`.
fn contents(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        // A temporary folder may vanish while it is read.
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                folders.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap_or_default();
                files.insert(path.strip_prefix(root).unwrap().to_path_buf(), bytes);
            }
        }
    }
    files
}

/// A short study on the virtual robot into `out` (under a second).
fn reproduce(out: &Path, trajectories: &str, seed: &str) -> std::process::Output {
    let run = sdnn(&[
        "reproduce",
        "--trajectories",
        trajectories,
        "--train",
        "2",
        "--duration",
        "2",
        "--seeds",
        "1",
        "--epochs",
        "2",
        "--seed",
        seed,
        "--out",
        s(out),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    run
}

/// Runs `sdnn args` and interrupts it (SIGINT) once a whole
/// `trajectory_01.csv` other than `old` is anywhere below `out` (written
/// in place or staged); it must exit 130.
fn interrupt_after_a_new_recording(args: &[&str], out: &Path, old: &[u8]) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_sdnn"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run sdnn");
    let started = Instant::now();
    let recorded = || {
        contents(out).iter().any(|(path, bytes)| {
            path.ends_with("trajectory_01.csv") && bytes != old && !bytes.is_empty()
        })
    };
    while !recorded() {
        assert!(started.elapsed() < Duration::from_secs(120), "no recording");
        std::thread::sleep(Duration::from_millis(10));
    }
    // SAFETY: kill(2) on the child's own process id.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    assert_eq!(child.wait().unwrap().code(), Some(130), "{args:?}");
}

/// A `reproduce` interrupted after recording over an earlier results
/// folder leaves that folder exactly as it was: no new recordings beside
/// the old results, networks and plots, and no temporary folder.
#[test]
fn an_interrupted_reproduce_leaves_the_earlier_results_whole() {
    let dir = Dir::new();
    let out = dir.path().join("results");
    reproduce(&out, "3", "1");
    dir.write("results/notes.txt", "the user's own");
    let before = contents(&out);
    let old_recording = &before[Path::new("data/trajectory_01.csv")];
    // Another seed records other trajectories; training never ends by itself.
    let args = [
        "reproduce",
        "--trajectories",
        "3",
        "--train",
        "2",
        "--duration",
        "2",
        "--seeds",
        "1",
        "--seed",
        "2",
        "--epochs",
        "100000",
        "--patience",
        "100000",
        "--out",
        s(&out),
    ];
    interrupt_after_a_new_recording(&args, &out, old_recording);
    let after = contents(&out);
    let changed: Vec<_> = after
        .keys()
        .chain(before.keys())
        .filter(|p| before.get(*p) != after.get(*p))
        .collect();
    assert!(changed.is_empty(), "changed: {changed:?}");
}

/// A completed run removes what the earlier run of the same command wrote
/// and it does not (recordings beyond a smaller count), says so, and keeps
/// every file it did not write, even in its own subfolders.
#[test]
fn a_rerun_removes_only_its_own_stale_files() {
    let dir = Dir::new();
    let out = dir.path().join("results");
    reproduce(&out, "5", "1");
    dir.write("results/notes.txt", "mine");
    dir.write("results/networks/mine.json", "{}");
    dir.write("results/data/trajectory_09.csv", "mine too");
    let run = reproduce(&out, "3", "1");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("removed 2 file(s) of the earlier run that this one does not write"),
        "{stderr}"
    );
    let files = contents(&out);
    for gone in ["data/trajectory_04.csv", "data/trajectory_05.csv"] {
        assert!(!files.contains_key(Path::new(gone)), "{gone} left");
    }
    for kept in [
        "data/trajectory_03.csv",
        "notes.txt",
        "networks/mine.json",
        "data/trajectory_09.csv",
        "results.md",
    ] {
        assert!(files.contains_key(Path::new(kept)), "{kept} missing");
    }
}

/// `study --data DIR/x.csv --out DIR`, run twice, keeps the recording it
/// reads and writes its results beside it.
#[test]
fn a_study_into_the_folder_of_its_recording_keeps_it() {
    let dir = Dir::new();
    let folder = dir.path().join("rec");
    let recording = crate::util::simulated_recordings(&dir, 1, 10.0).remove(0);
    let mine = folder.join("x.csv");
    std::fs::rename(&recording, &mine).unwrap();
    let original = std::fs::read(&mine).unwrap();
    for _ in 0..2 {
        let run = sdnn(&[
            "study",
            "--model",
            "kinova_gen3_lite_3dof",
            "--data",
            s(&mine),
            "--test-from",
            "7",
            "--seeds",
            "1",
            "--epochs",
            "2",
            "--out",
            s(&folder),
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    assert_eq!(std::fs::read(&mine).unwrap(), original);
    assert!(folder.join("results.md").exists());
}

/// `simulate` into a folder of more earlier recordings than it writes is
/// refused (random or planned motion), and an interrupted `simulate`
/// leaves the earlier recordings as they were.
#[test]
fn simulate_leaves_no_stale_or_mixed_recordings() {
    let dir = Dir::new();
    let out = dir.path().join("rec");
    crate::util::simulated_recordings(&dir, 3, 1.0);
    let plan = dir.path().join("plan.csv");
    let designed = sdnn(&[
        "excite",
        "--model",
        "kinova_gen3_lite_3dof",
        "--duration",
        "2",
        "--rounds",
        "1",
        "--out",
        s(&plan),
    ]);
    assert!(
        designed.status.success(),
        "{}",
        String::from_utf8_lossy(&designed.stderr)
    );
    let planned = sdnn(&["simulate", "--trajectory", s(&plan), "--out", s(&out)]);
    let stderr = String::from_utf8_lossy(&planned.stderr);
    assert_eq!(planned.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("holds 2 recording(s) of an earlier run beyond --count 1"),
        "{stderr}"
    );
    let before = contents(&out);
    let old_recording = &before[Path::new("trajectory_01.csv")];
    // About 0.4 s per recording: interrupted between two.
    let args = [
        "simulate",
        "--count",
        "3",
        "--duration",
        "60",
        "--seed",
        "2",
        "--out",
        s(&out),
    ];
    interrupt_after_a_new_recording(&args, &out, old_recording);
    assert_eq!(contents(&out), before);
}
