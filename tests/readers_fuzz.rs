//! Every reader against thousands of malformed inputs: valid files with
//! random bytes replaced, inserted, deleted or cut. Each read must return a
//! value or an error that names the file, never panic (proptest fails the
//! case on a panic) and never hang.

use std::path::Path;

use proptest::prelude::*;

use crate::util::root;

/// Bytes that matter to the formats: separators, digits, exponents,
/// brackets, quotes, tags, NaN and infinity spellings, invalid UTF-8.
const PALETTE: &[u8] = b"0123456789,.;-+eE\n\r \t=[]{}\"'<>/:NaInfnaxyz#\x00\xff";

/// Random edits: (position, kind, palette index).
fn edits() -> impl Strategy<Value = Vec<(usize, u8, usize)>> {
    proptest::collection::vec((any::<usize>(), 0u8..4, 0..PALETTE.len()), 1..6)
}

fn mutate(base: &[u8], edits: &[(usize, u8, usize)]) -> Vec<u8> {
    let mut bytes = base.to_vec();
    for &(at, kind, k) in edits {
        let at = at % (bytes.len() + 1);
        match kind {
            0 if at < bytes.len() => bytes[at] = PALETTE[k],
            1 => bytes.insert(at, PALETTE[k]),
            2 if at < bytes.len() => {
                bytes.remove(at);
            }
            3 => bytes.truncate(at),
            _ => {}
        }
    }
    bytes
}

fn cases() -> ProptestConfig {
    ProptestConfig {
        cases: 2000,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn recording() -> String {
    let mut text = String::from("t,q1,q2,qd1,qd2,tau1,tau2\n");
    for k in 0..12 {
        let t = f64::from(k) * 0.01;
        text.push_str(&format!(
            "{t},{},{},0.5,-0.25,1.5,-2e-3\n",
            t.sin(),
            t.cos()
        ));
    }
    text
}

fn assert_names_file(error: &dyn std::fmt::Display, file: &Path) {
    let text = error.to_string();
    let name = file.file_name().unwrap().to_string_lossy();
    assert!(
        text.contains(name.as_ref()),
        "error without the file: {text}"
    );
}

proptest! {
    #![proptest_config(cases())]

    #[test]
    fn csv_recordings(edits in edits()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.csv");
        std::fs::write(&path, mutate(recording().as_bytes(), &edits)).unwrap();
        let options = sdnn::trajectory::ReadOptions {
            min_samples: 1,
            ..Default::default()
        };
        if let Err(e) = sdnn::trajectory::read_csv(&path, &options) {
            assert_names_file(&e, &path);
        }
        let states = recording().replace("tau1,tau2", "qdd1,qdd2");
        std::fs::write(&path, mutate(states.as_bytes(), &edits)).unwrap();
        if let Err(e) = sdnn::trajectory::read_states_csv(&path, &options) {
            assert_names_file(&e, &path);
        }
    }

    #[test]
    fn toml_descriptions(edits in edits()) {
        let base = std::fs::read(root().join("models/planar_2link.toml")).unwrap();
        let text = String::from_utf8_lossy(&mutate(&base, &edits)).into_owned();
        let path = Path::new("models/fuzzed.toml");
        if let Err(e) = codegen::Description::parse(&text, "fuzzed", path) {
            assert_names_file(&e, path);
        }
    }

    #[test]
    fn urdf_files(edits in edits()) {
        let base = "<robot name='r'><link name='base'/>\
            <link name='a'><inertial><origin xyz='0.1 0 0' rpy='0 0 0'/><mass value='1.5'/>\
            <inertia ixx='0.01' iyy='0.02' izz='0.03' ixy='0' ixz='0' iyz='0'/></inertial></link>\
            <link name='b'><inertial><mass value='0.5'/>\
            <inertia ixx='0.001' iyy='0.001' izz='0.001' ixy='0' ixz='0' iyz='0'/></inertial></link>\
            <joint name='j1' type='revolute'><parent link='base'/><child link='a'/>\
            <origin xyz='0 0 0.1' rpy='0 0 0'/><axis xyz='0 0 1'/>\
            <limit lower='-1' upper='1' effort='5' velocity='2'/></joint>\
            <joint name='j2' type='revolute'><parent link='a'/><child link='b'/>\
            <origin xyz='0.3 0 0' rpy='1.5707963 0 0'/><axis xyz='0 1 0'/>\
            <limit lower='-1' upper='1' effort='5' velocity='2'/></joint></robot>";
        let text = String::from_utf8_lossy(&mutate(base.as_bytes(), &edits)).into_owned();
        let options = sdnn::import_urdf::ImportOptions::default();
        if let Ok(imported) = sdnn::import_urdf::import_urdf(&text, "fuzzed.urdf", &options) {
            // Whatever imports must be a description that parses or says why.
            let _ = codegen::Description::parse(&imported.toml, "fuzzed", Path::new("f.toml"));
        }
    }

    #[test]
    fn network_files(edits in edits()) {
        let base = network_json();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("net.json");
        std::fs::write(&path, mutate(base.as_bytes(), &edits)).unwrap();
        if let Err(e) = sdnn::mlp::Mlp::load(&path) {
            assert_names_file(&e, &path);
        }
    }

    #[test]
    fn per_channel_logs(edits in edits(), which in 0usize..4) {
        let dir = tempfile::tempdir().unwrap();
        let lines = |f: &dyn Fn(usize) -> String| (0..8).map(f).collect::<Vec<_>>().join("\n");
        let mut texts = [
            lines(&|k| format!("{}", k as f64 * 0.01)),
            lines(&|k| format!("{} {}", k as f64 * 0.1, -(k as f64))),
            lines(&|_| "0.5 0.25".into()),
            lines(&|_| "1 -1".into()),
        ]
        .map(String::into_bytes);
        texts[which] = mutate(&texts[which], &edits);
        let names = ["time.txt", "q.txt", "qd.txt", "tau.txt"];
        for (name, text) in names.iter().zip(&texts) {
            std::fs::write(dir.path().join(name), text).unwrap();
        }
        let sources = sdnn::import_log::LineMajorSources {
            time: dir.path().join(names[0]),
            positions: dir.path().join(names[1]),
            velocities: dir.path().join(names[2]),
            torques: dir.path().join(names[3]),
            dof: 2,
        };
        if let Err(e) = sdnn::import_log::read_line_major(&sources) {
            assert!(names.iter().any(|n| e.to_string().contains(n)), "{e}");
        }
    }
}

/// A small valid network file, trained once.
fn network_json() -> String {
    use std::sync::OnceLock;
    static JSON: OnceLock<String> = OnceLock::new();
    JSON.get_or_init(|| {
        let x = nalgebra::DMatrix::from_fn(40, 2, |r, c| (r as f64 * 0.1 + c as f64).sin());
        let y = nalgebra::DMatrix::from_fn(40, 1, |r, _| x[(r, 0)] * 2.0);
        let groups = (0..40).map(|r| r % 4).collect();
        let data = sdnn::mlp::Dataset::new(x, y, Some(groups)).unwrap();
        let network = sdnn::mlp::Mlp::params()
            .hidden(vec![3])
            .max_epochs(2)
            .check()
            .unwrap()
            .fit(&data)
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("net.json");
        network.save(&path).unwrap();
        std::fs::read_to_string(path).unwrap()
    })
    .clone()
}
