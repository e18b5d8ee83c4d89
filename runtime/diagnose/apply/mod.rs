//! Writes diagnosed effects into a robot description, keeping the user's
//! comments and formatting (toml_edit), atomically, with a backup.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use toml_edit::{Array, ArrayOfTables, DocumentMut, InlineTable, Item, Table, Value};

use super::diagnosis::Diagnosis;
use super::kind::Kind;

/// Radius of the sphere whose inertia a payload without a fitted moment of
/// its own gets (a point mass would have none, which the description
/// rejects as not positive definite).
const PAYLOAD_RADIUS: f64 = 0.02;

/// Adds the effects of `diagnosis` to the description text. Joint effects add
/// to the joint's existing values (the diagnosis measured what is missing);
/// a payload becomes a fixed child body of the last moving link.
pub fn apply_to_text(
    source: &str,
    diagnosis: &Diagnosis,
    joints: &[&str],
    last_link: &str,
) -> Result<String> {
    // The file's byte-order mark and line endings are the user's: kept.
    let bom = source.starts_with('\u{feff}');
    let crlf = source.contains("\r\n");
    let mut doc: DocumentMut = source
        .trim_start_matches('\u{feff}')
        .parse()
        .context("the description is not valid TOML")?;
    // A joint's effects are in the robot's torque already, on a joint with
    // a torque scale too (`applied_units`): written as reported.
    for effect in &diagnosis.effects {
        let value = |name: &str| {
            effect
                .parameters
                .get(name)
                .and_then(serde_json::Value::as_f64)
        };
        match (effect.kind, effect.joint) {
            (Kind::Payload, _) => {
                let mass = value("mass").context("payload without mass")?;
                let com = vector(&effect.parameters, "com")?;
                let com = com
                    .iter()
                    .zip(["x", "y", "z"])
                    .map(|(c, axis)| {
                        c.with_context(|| {
                            format!(
                                "the payload's COM {axis} component was not identifiable from the \
                                 data (null in the diagnosis): record motions that determine it, \
                                 or add the payload by hand"
                            )
                        })
                    })
                    .collect::<Result<Vec<f64>>>()?;
                let parent = effect.link.as_deref().unwrap_or(last_link);
                // Without a fitted moment the payload gets a small sphere's.
                let moment = value("inertia")
                    .filter(|&j| j > 0.0)
                    .unwrap_or(0.4 * mass * PAYLOAD_RADIUS * PAYLOAD_RADIUS);
                add_payload(&mut doc, mass, &com, moment, parent)?;
            }
            (Kind::InertialError, _) if effect.parameters.contains_key("inertia") => {
                let link = effect
                    .link
                    .as_deref()
                    .context("inertial error without a link")?;
                let body = |prefix: &str| -> Result<[f64; 10]> {
                    let mass = value(&format!("{prefix}mass")).context("missing mass")?;
                    let com = numbers(&effect.parameters, &format!("{prefix}com"), 3)?;
                    let inertia = numbers(&effect.parameters, &format!("{prefix}inertia"), 6)?;
                    Ok(body::standard(
                        mass,
                        std::array::from_fn(|k| com[k]),
                        std::array::from_fn(|k| inertia[k]),
                    ))
                };
                let (named, nominal) = (body("")?, body("nominal_")?);
                let change = std::array::from_fn(|k| named[k] - nominal[k]);
                body::correct_whole(link_table(&mut doc, link)?, link, &change)?;
            }
            (Kind::InertialError, _) => {
                let link = effect
                    .link
                    .as_deref()
                    .context("inertial error without a link")?;
                let nominal_mass = value("nominal_mass").context("missing nominal_mass")?;
                let nominal_com = vector(&effect.parameters, "nominal_com")?;
                let nominal_com: Vec<f64> = nominal_com
                    .iter()
                    .map(|c| c.context("nominal_com must be numbers"))
                    .collect::<Result<_>>()?;
                let (mass, com) = match value("mass") {
                    Some(mass) => {
                        // A component the data did not determine stays as modelled.
                        let com: Vec<f64> = vector(&effect.parameters, "com")?
                            .iter()
                            .zip(&nominal_com)
                            .map(|(c, n)| c.unwrap_or(*n))
                            .collect();
                        (mass, com)
                    }
                    // The mass was not identifiable: never change it. The
                    // diagnosis fitted the first moment with the mass as
                    // modelled, so the COM moves to first_moment / mass
                    // (a null component stays as modelled).
                    None => {
                        let moment =
                            vector(&effect.parameters, "first_moment").with_context(|| {
                                format!(
                                    "link `{link}`: the diagnosis gives neither a mass nor a first \
                                 moment"
                                )
                            })?;
                        if !nominal_mass.is_finite() || nominal_mass <= 0.0 {
                            bail!("link `{link}`: no positive modelled mass to hold");
                        }
                        let com = moment
                            .iter()
                            .zip(&nominal_com)
                            .map(|(h, n)| h.map_or(*n, |h| h / nominal_mass))
                            .collect();
                        (nominal_mass, com)
                    }
                };
                correct_link(&mut doc, link, mass, &com, nominal_mass, &nominal_com)?;
            }
            // Properties of the recording, not of the robot: corrected
            // with evaluate's and diagnose's options, not in the TOML.
            (Kind::TorqueScale | Kind::TorqueDelay, _) => {}
            (Kind::JointSpring, Some(joint)) => {
                let name = joints.get(joint - 1).context("joint index out of range")?;
                let stiffness = value("stiffness").context("spring without stiffness")?;
                let rest = value("rest").context("spring without rest angle")?;
                add_spring(&mut doc, name, stiffness, rest)?;
            }
            (Kind::GravityDirection, _) => {
                let gravity: Vec<f64> = vector(&effect.parameters, "gravity")?
                    .into_iter()
                    .map(|g| g.context("gravity must be numbers"))
                    .collect::<Result<_>>()?;
                let mut array = Array::new();
                for g in gravity {
                    array.push(g);
                }
                set_keeping_decor(doc.as_table_mut(), "gravity", Value::Array(array));
            }
            (kind, Some(joint)) => {
                if kind.joint_parameters().next().is_none() {
                    bail!("{} is not an effect of a joint", kind.name());
                }
                let name = joints.get(joint - 1).context("joint index out of range")?;
                let (mut amounts, mut shape) = (Vec::new(), None);
                for p in kind.joint_parameters() {
                    let Some(key) = p.key else { continue };
                    let fitted = value(p.name)
                        .with_context(|| format!("{} without {}", kind.name(), p.name))?;
                    if p.shape {
                        shape = Some((key, fitted));
                    } else {
                        amounts.push((key, fitted));
                    }
                }
                match shape {
                    // A Stribeck velocity, a ripple's cycles.
                    Some(shape) => add_shaped(&mut doc, name, &amounts, shape)?,
                    None => {
                        for (key, amount) in amounts {
                            add_joint_effect(&mut doc, name, key, amount)?;
                        }
                    }
                }
            }
            (kind, None) => bail!("{kind:?} has no joint"),
        }
    }
    let mut text = doc.to_string().replace("\r\n", "\n");
    if crlf {
        text = text.replace('\n', "\r\n");
    }
    if bom {
        text.insert(0, '\u{feff}');
    }
    Ok(text)
}

/// Adds a spring k (q - rest) to a joint's: the stiffnesses add, the rest
/// angle is the stiffness-weighted mean (k0 (q - r0) + k (q - r) =
/// (k0 + k)(q - r')).
fn add_spring(doc: &mut DocumentMut, joint: &str, stiffness: f64, rest: f64) -> Result<()> {
    let (k0, r0) = (
        joint_effect(doc, joint, "spring"),
        joint_effect(doc, joint, "spring_rest"),
    );
    let total = k0 + stiffness;
    let mean_rest = if total != 0.0 {
        (k0 * r0 + stiffness * rest) / total
    } else {
        rest
    };
    add_joint_effect(doc, joint, "spring", stiffness)?;
    let delta = mean_rest - r0;
    add_joint_effect(doc, joint, "spring_rest", delta)
}

/// Adds `amplitudes` to a joint's effect whose columns `shape` (a Stribeck
/// velocity, a ripple's cycles) shapes: the shape is set where the joint
/// has none of the effect yet, and must match where it has (two Stribeck
/// velocities or two ripple harmonics are not one term).
fn add_shaped(
    doc: &mut DocumentMut,
    joint: &str,
    amplitudes: &[(&str, f64)],
    shape: (&str, f64),
) -> Result<()> {
    let (key, value) = shape;
    let present = amplitudes
        .iter()
        .any(|(k, _)| joint_effect(doc, joint, k) != 0.0);
    let existing = joint_effect(doc, joint, key);
    if present && existing != value {
        bail!(
            "joint `{joint}` already has this effect with {key} = {existing}; the diagnosis \
             found more of it with {key} = {value}: one term cannot hold both, edit the \
             description by hand"
        );
    }
    for &(k, amplitude) in amplitudes {
        add_joint_effect(doc, joint, k, amplitude)?;
    }
    if value == existing {
        // A correction of the effect the joint has: its shape line is
        // left as written (`ripple_cycles = 6` stays an integer).
        return Ok(());
    }
    add_joint_effect(doc, joint, key, value - existing)
}

/// A joint's effect value in the document (0 when absent).
fn joint_effect(doc: &DocumentMut, joint: &str, key: &str) -> f64 {
    doc.get("joints")
        .and_then(Item::as_array_of_tables)
        .and_then(|joints| {
            joints
                .iter()
                .find(|t| t.get("name").and_then(Item::as_str) == Some(joint))
        })
        .and_then(|t| t.get("effects"))
        .and_then(|e| e.get(key))
        .and_then(number)
        .unwrap_or(0.0)
}

fn add_joint_effect(doc: &mut DocumentMut, joint: &str, key: &str, delta: f64) -> Result<()> {
    let joints = doc
        .get_mut("joints")
        .and_then(Item::as_array_of_tables_mut)
        .context("the description has no [[joints]]")?;
    let table = joints
        .iter_mut()
        .find(|t| t.get("name").and_then(Item::as_str) == Some(joint))
        .with_context(|| format!("no joint named `{joint}` in the description"))?;
    if !table.contains_key("effects") {
        table.insert(
            "effects",
            Item::Value(Value::InlineTable(InlineTable::new())),
        );
    }
    let effects = table.get_mut("effects").context("effects")?;
    let current = effects.get(key).and_then(number).unwrap_or(0.0);
    let updated = current + delta;
    match effects {
        Item::Value(Value::InlineTable(t)) => match t.get_mut(key) {
            Some(old) => keep_decor(old, updated.into()),
            None => insert_last(t, key, updated.into()),
        },
        Item::Table(t) => set_keeping_decor(t, key, updated.into()),
        _ => bail!("`effects` of joint `{joint}` is not a table"),
    }
    Ok(())
}

/// Adds `key` at the end of an inline table; the space before its closing
/// brace moves with the end (`{ a = 1 }` gets `{ a = 1, b = 2 }`, not
/// `{ a = 1 , b = 2}`).
fn insert_last(table: &mut InlineTable, key: &str, mut value: Value) {
    if let Some((_, last)) = table.iter_mut().last() {
        let suffix = last.decor().suffix().cloned();
        if let Some(suffix) = suffix {
            last.decor_mut().set_suffix("");
            value.decor_mut().set_suffix(suffix);
        }
    }
    table.insert(key, value);
}

/// Replaces `old` by `value` with `old`'s spaces and comments (a trailing
/// `# measured on the bench` stays on its line).
fn keep_decor(old: &mut Value, mut value: Value) {
    *value.decor_mut() = old.decor().clone();
    *old = value;
}

/// A parameter of `count` numbers.
fn numbers(
    parameters: &serde_json::Map<String, serde_json::Value>,
    name: &str,
    count: usize,
) -> Result<Vec<f64>> {
    let values: Option<Vec<f64>> = parameters
        .get(name)
        .and_then(serde_json::Value::as_array)
        .filter(|v| v.len() == count)
        .and_then(|v| v.iter().map(serde_json::Value::as_f64).collect());
    values.with_context(|| format!("`{name}` must be {count} numbers"))
}

/// The `[[links]]` table of `link`.
fn link_table<'a>(doc: &'a mut DocumentMut, link: &str) -> Result<&'a mut Table> {
    doc.get_mut("links")
        .and_then(Item::as_array_of_tables_mut)
        .context("the description has no [[links]]")?
        .iter_mut()
        .find(|t| t.get("name").and_then(Item::as_str) == Some(link))
        .with_context(|| format!("no link named `{link}` in the description"))
}

/// A 3-vector parameter whose entries may be null (not identifiable).
fn vector(
    parameters: &serde_json::Map<String, serde_json::Value>,
    name: &str,
) -> Result<Vec<Option<f64>>> {
    let values = parameters
        .get(name)
        .and_then(serde_json::Value::as_array)
        .with_context(|| format!("missing `{name}`"))?;
    if values.len() != 3 {
        bail!("`{name}` must have 3 entries, found {}", values.len());
    }
    Ok(values.iter().map(serde_json::Value::as_f64).collect())
}

/// Corrects a link's mass and COM by the diagnosed change of the body: the
/// mass and first moment change by (mass - nominal) and
/// (mass * com - nominal_mass * nominal_com), so a link whose body also
/// lumps fixed children gets the change, not the lumped values. The inertia
/// about the link's COM is kept (the diagnosis assumes it as modelled).
fn correct_link(
    doc: &mut DocumentMut,
    link: &str,
    mass: f64,
    com: &[f64],
    nominal_mass: f64,
    nominal_com: &[f64],
) -> Result<()> {
    let table = link_table(doc, link)?;
    let own_mass = table.get("mass").and_then(number).unwrap_or(0.0);
    let own_com: Vec<f64> = match table.get("com").and_then(Item::as_array) {
        Some(a) => a.iter().map(|v| value_number(v).unwrap_or(0.0)).collect(),
        None => vec![0.0; 3],
    };
    if own_com.len() != 3 {
        bail!("link `{link}`: `com` must have 3 entries");
    }
    let new_mass = own_mass + (mass - nominal_mass);
    if !new_mass.is_finite() || new_mass <= 0.0 {
        bail!("link `{link}`: the corrected mass {new_mass} kg is not positive");
    }
    let new_com: Vec<f64> = (0..3)
        .map(|k| (own_mass * own_com[k] + mass * com[k] - nominal_mass * nominal_com[k]) / new_mass)
        .collect();
    set_keeping_decor(table, "mass", Value::from(new_mass));
    set_keeping_decor(
        table,
        "com",
        Value::Array(new_com.iter().copied().collect::<Array>()),
    );
    Ok(())
}

fn number(item: &Item) -> Option<f64> {
    item.as_value().and_then(value_number)
}

fn value_number(value: &Value) -> Option<f64> {
    value
        .as_float()
        .or_else(|| value.as_integer().map(|i| i as f64))
}

/// Replaces a key's value, keeping the comments around it.
fn set_keeping_decor(table: &mut Table, key: &str, value: Value) {
    match table.get_mut(key).and_then(Item::as_value_mut) {
        Some(old) => keep_decor(old, value),
        None => {
            table.insert(key, Item::Value(value));
        }
    }
}

fn add_payload(
    doc: &mut DocumentMut,
    mass: f64,
    com: &[f64],
    moment: f64,
    parent: &str,
) -> Result<()> {
    if !mass.is_finite() || mass <= 0.0 || com.len() != 3 {
        bail!("payload needs a positive mass and a 3-vector COM, found {mass} and {com:?}");
    }
    if !moment.is_finite() || moment <= 0.0 {
        bail!("payload needs a positive moment of inertia, found {moment}");
    }
    let name = unique_link_name(doc, "payload");
    let mut link = Table::new();
    link.insert("name", toml_edit::value(name.clone()));
    link.insert("mass", toml_edit::value(mass));
    link.insert(
        "com",
        toml_edit::value(com.iter().copied().collect::<Array>()),
    );
    let mut inertia = InlineTable::new();
    for key in ["ixx", "iyy", "izz"] {
        inertia.insert(key, moment.into());
    }
    link.insert("inertia", toml_edit::value(inertia));
    push(doc, "links", link)?;
    let mut joint = Table::new();
    joint.insert("name", toml_edit::value(format!("{name}_mount")));
    joint.insert("type", toml_edit::value("fixed"));
    joint.insert("parent", toml_edit::value(parent));
    joint.insert("child", toml_edit::value(name));
    push(doc, "joints", joint)
}

fn push(doc: &mut DocumentMut, key: &str, table: Table) -> Result<()> {
    if !doc.contains_key(key) {
        doc.insert(key, Item::ArrayOfTables(ArrayOfTables::new()));
    }
    doc.get_mut(key)
        .and_then(Item::as_array_of_tables_mut)
        .with_context(|| format!("`{key}` is not an array of tables"))?
        .push(table);
    Ok(())
}

fn unique_link_name(doc: &DocumentMut, base: &str) -> String {
    let taken = |name: &str| {
        doc.get("links")
            .and_then(Item::as_array_of_tables)
            .is_some_and(|links| {
                links
                    .iter()
                    .any(|l| l.get("name").and_then(Item::as_str) == Some(name))
            })
    };
    (1..)
        .map(|k| {
            if k == 1 {
                base.to_string()
            } else {
                format!("{base}{k}")
            }
        })
        .find(|n| !taken(n))
        .unwrap_or_else(|| base.to_string())
}

/// What `apply_to_file` did: the backup and the changed lines.
pub struct Applied {
    pub backup: PathBuf,
    /// `- old` / `+ new` lines, in file order.
    pub changes: Vec<String>,
}

/// Rewrites `path` with the effects: validates the result as a description,
/// keeps a `.bak` copy, writes a temporary file and renames it into place.
pub fn apply_to_file(
    path: &Path,
    diagnosis: &Diagnosis,
    joints: &[&str],
    last_link: &str,
) -> Result<Applied> {
    let source = crate::bounded::read_description(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let updated = apply_to_text(&source, diagnosis, joints, last_link)
        .with_context(|| path.display().to_string())?;
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("model");
    codegen::Description::parse(&updated, stem, path)
        .context("the updated description does not validate")?;
    if updated == source {
        // Only properties of the data were named: nothing to write.
        return Ok(Applied {
            backup: path.with_extension("toml.bak"),
            changes: Vec::new(),
        });
    }
    // The first backup is the original: a later --apply never replaces it.
    let backup = path.with_extension("toml.bak");
    if !backup.exists() {
        crate::output::write(&backup, source.as_bytes())
            .with_context(|| format!("{}: cannot write backup", backup.display()))?;
    }
    crate::output::replace_input(path, updated.as_bytes())
        .with_context(|| format!("{}: cannot replace", path.display()))?;
    let mut changes = changed_lines(&source, &updated);
    let crlf = source.matches("\r\n").count();
    let lf = source.matches('\n').count() - crlf;
    if crlf > 0 && lf > 0 {
        changes.push(format!(
            "(the file mixed line ends; its {lf} LF line ends are CRLF now, as its other {crlf})"
        ));
    }
    Ok(Applied { backup, changes })
}

/// The lines that differ between `old` and `new` as `- line` and `+ line`
/// (a longest-common-subsequence diff; descriptions are short).
fn changed_lines(old: &str, new: &str) -> Vec<String> {
    let (a, b): (Vec<&str>, Vec<&str>) = (old.lines().collect(), new.lines().collect());
    if a.len().saturating_mul(b.len()) > 4_000_000 {
        return vec![format!("({} lines before, {} after)", a.len(), b.len())];
    }
    // common[i][j]: longest common subsequence of a[i..] and b[j..].
    let mut common = vec![vec![0u32; b.len() + 1]; a.len() + 1];
    for i in (0..a.len()).rev() {
        for j in (0..b.len()).rev() {
            common[i][j] = if a[i] == b[j] {
                common[i + 1][j + 1] + 1
            } else {
                common[i + 1][j].max(common[i][j + 1])
            };
        }
    }
    let (mut i, mut j, mut out) = (0, 0, Vec::new());
    while i < a.len() || j < b.len() {
        if i < a.len() && j < b.len() && a[i] == b[j] {
            (i, j) = (i + 1, j + 1);
        } else if i < a.len() && (j == b.len() || common[i + 1][j] >= common[i][j + 1]) {
            out.push(format!("{}- {}", place(&a, i), a[i]));
            i += 1;
        } else {
            out.push(format!("{}+ {}", place(&b, j), b[j]));
            j += 1;
        }
    }
    out
}

/// "joint `name`: " for a line inside a `[[joints]]` table (likewise a
/// link), so that seven `effects = ...` lines say whose they are; empty
/// outside a named table.
fn place(lines: &[&str], at: usize) -> String {
    let header = |l: &str| l.trim_start().starts_with('[');
    let Some(start) = (0..=at).rev().find(|&k| header(lines[k])) else {
        return String::new();
    };
    let table = lines[start].trim().trim_matches(|c| c == '[' || c == ']');
    let end = (start + 1..lines.len())
        .find(|&k| header(lines[k]))
        .unwrap_or(lines.len());
    let name = lines[start + 1..end].iter().find_map(|l| {
        let value = l
            .trim()
            .strip_prefix("name")?
            .trim_start()
            .strip_prefix('=')?;
        Some(value.trim().trim_matches('"').to_string())
    });
    match (table, name) {
        ("joints", Some(name)) => format!("joint `{name}`: "),
        ("links", Some(name)) => format!("link `{name}`: "),
        _ => String::new(),
    }
}

mod body;
#[cfg(test)]
mod tests;
