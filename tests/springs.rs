//! A joint spring end to end: a plant description with a spring, recorded
//! by `sdnn simulate`, diagnosed, written into a copy of the nominal TOML by
//! `--apply`, and the printed `evaluate` command closes the gap with no
//! rebuild.

use crate::util::{Dir, root, sdnn};

const NOMINAL: &str = "kinova_gen3_lite_3dof";

#[test]
fn a_spring_is_named_applied_and_closes_the_gap() {
    let dir = Dir::new();
    let nominal = std::fs::read_to_string(root().join(format!("models/{NOMINAL}.toml"))).unwrap();
    let at = nominal.find("name = \"joint3\"").unwrap();
    let axis = at + nominal[at..].find("\naxis").unwrap();
    let end = axis + 1 + nominal[axis + 1..].find('\n').unwrap();
    let plant = format!(
        "{}\neffects = {{ spring = 2.0, spring_rest = 0.3 }}{}",
        &nominal[..end],
        &nominal[end..]
    );
    let plant = dir.write("plant.toml", &plant);
    let data = dir.path().join("data");
    let run = sdnn(&[
        "simulate",
        "--plant",
        plant.to_str().unwrap(),
        "--count",
        "3",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let files: Vec<String> = (1..=3)
        .map(|k| {
            data.join(format!("trajectory_{k:02}.csv"))
                .display()
                .to_string()
        })
        .collect();
    let copy = dir.write("arm.toml", &nominal);
    let mut args = vec!["diagnose", "--model", NOMINAL, "--apply", "--toml"];
    args.push(copy.to_str().unwrap());
    args.push("--data");
    args.extend(files.iter().map(String::as_str));
    let run = sdnn(&args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let report = String::from_utf8_lossy(&run.stdout);
    assert!(
        report
            .lines()
            .any(|l| l.trim_start().starts_with("joint_spring") && l.contains("joint 3 ")),
        "{report}"
    );
    let written = std::fs::read_to_string(&copy).unwrap();
    let value = |key: &str| -> f64 {
        let from = written.find(&format!("{key} = ")).unwrap() + key.len() + 3;
        written[from..]
            .split([',', ' ', '}'])
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!((value("spring") - 2.0).abs() < 0.02, "{written}");
    assert!((value("spring_rest") - 0.3).abs() < 0.01, "{written}");
    let mse = |model: &str| -> f64 {
        let mut args = vec!["evaluate", "--model", model, "--format", "json", "--data"];
        args.extend(files.iter().map(String::as_str));
        crate::util::sdnn_json(&args)["mse"][2].as_f64().unwrap()
    };
    let (before, after) = (mse(NOMINAL), mse(copy.to_str().unwrap()));
    assert!(after < 0.01 * before, "joint 3: {before} -> {after}");
}
