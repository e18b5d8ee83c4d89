//! Renders the imported links and joints as description TOML.

use toml_edit::{Array, ArrayOfTables, DocumentMut, InlineTable, Item, Table, Value};

use super::ImportOptions;
use super::convert::{JointOut, KindOut, LinkOut};

/// The header comment: where the description came from and the options
/// that reproduce it. Every name is written escaped ({:?}): a comment line
/// cannot be ended by the URDF's text.
pub(super) fn header(
    source: &str,
    robot: &str,
    base: &str,
    tip: &str,
    options: &ImportOptions,
) -> String {
    let mut flags = vec![format!("--base {base:?}"), format!("--tip {tip:?}")];
    flags.extend(
        options
            .lock
            .iter()
            .map(|(j, a)| format!("--lock {:?}", format!("{j}={a:?}"))),
    );
    flags.extend(
        options
            .attach
            .iter()
            .map(|a| format!("--attach {:?}", a.to_string())),
    );
    flags.extend(
        options
            .nonphysical_inertia
            .iter()
            .map(|l| format!("--nonphysical-inertia {l:?}")),
    );
    if let Some(name) = &options.name {
        flags.push(format!("--name {name:?}"));
    }
    format!(
        "# Imported by `sdnn import-urdf` from {source:?}\n# URDF robot {robot:?}, options: {}\n",
        flags.join(" ")
    )
}

pub(super) fn render(
    name: &str,
    gravity: [f64; 3],
    links: &[LinkOut],
    joints: &[JointOut],
) -> String {
    let mut doc = DocumentMut::new();
    doc["name"] = toml_edit::value(name);
    doc["gravity"] = toml_edit::value(float_array(&gravity));
    let mut link_tables = ArrayOfTables::new();
    for link in links {
        link_tables.push(link_table(link));
    }
    let mut joint_tables = ArrayOfTables::new();
    for joint in joints {
        joint_tables.push(joint_table(joint));
    }
    doc["links"] = Item::ArrayOfTables(link_tables);
    doc["joints"] = Item::ArrayOfTables(joint_tables);
    doc.to_string()
}

fn link_table(link: &LinkOut) -> Table {
    let mut t = Table::new();
    let comment: String = link
        .comment
        .iter()
        .flat_map(|c| c.lines())
        .map(|line| format!("# {line}\n"))
        .collect();
    t.decor_mut().set_prefix(format!("\n{comment}"));
    t["name"] = toml_edit::value(&link.name);
    if let Some(b) = &link.body {
        t["mass"] = toml_edit::value(float(b.mass));
        t["com"] = toml_edit::value(float_array(&b.com));
        let keys = ["ixx", "iyy", "izz", "ixy", "ixz", "iyz"];
        t["inertia"] = toml_edit::value(inline(
            keys.iter().zip(b.inertia).map(|(k, v)| (*k, float(v))),
        ));
    }
    if let Some(why) = &link.nonphysical {
        t["nonphysical_inertia"] = toml_edit::value(why);
    }
    t
}

fn joint_table(joint: &JointOut) -> Table {
    let mut t = Table::new();
    t.decor_mut().set_prefix("\n");
    t["name"] = toml_edit::value(&joint.name);
    t["type"] = toml_edit::value(match joint.kind {
        KindOut::Revolute => "revolute",
        KindOut::Prismatic => "prismatic",
        KindOut::Fixed => "fixed",
    });
    t["parent"] = toml_edit::value(&joint.parent);
    t["child"] = toml_edit::value(&joint.child);
    let mut origin = vec![("xyz", Value::Array(float_array(&joint.xyz)))];
    if joint.rpy != [0.0; 3] {
        origin.push(("rpy", Value::Array(float_array(&joint.rpy))));
    }
    t["origin"] = toml_edit::value(inline(origin));
    if joint.kind != KindOut::Fixed {
        t["axis"] = toml_edit::value(float_array(&joint.axis));
    }
    if let Some(l) = joint.limits {
        let entries = [
            ("lower", l.lower),
            ("upper", l.upper),
            ("velocity", l.velocity),
            ("effort", l.effort),
        ];
        let present = entries
            .into_iter()
            .filter_map(|(k, v)| Some((k, float(v?))));
        t["limits"] = toml_edit::value(inline(present));
    }
    if let Some(value) = joint.locked {
        t["locked"] = toml_edit::value(float(value));
    }
    if let Some(m) = &joint.mimic {
        let mut table = InlineTable::new();
        table.insert("joint", Value::from(m.joint.as_str()));
        table.insert("multiplier", float(m.multiplier));
        table.insert("offset", float(m.offset));
        table.fmt();
        t["mimic"] = toml_edit::value(table);
    }
    if let Some((viscous, coulomb)) = joint.effects {
        t["effects"] = toml_edit::value(inline([
            ("viscous", float(viscous)),
            ("coulomb", float(coulomb)),
        ]));
    }
    t
}

fn inline<'k>(entries: impl IntoIterator<Item = (&'k str, Value)>) -> InlineTable {
    let mut table = InlineTable::new();
    for (k, v) in entries {
        table.insert(k, v);
    }
    table.fmt();
    table
}

/// A float in Rust's shortest round-trip form (`{:?}`: `0.35`, `3.9e-7`),
/// with -0.0 printed as 0.0.
fn float(x: f64) -> Value {
    let x = x + 0.0;
    format!("{x:?}").parse().unwrap_or_else(|_| Value::from(x))
}

fn float_array(v: &[f64]) -> Array {
    let mut array: Array = v.iter().map(|&x| float(x)).collect();
    array.fmt();
    array
}
