//! A whole-body inertial error written into a link: its mass, centre of
//! mass and inertia about the COM changed by the diagnosed change of the
//! body's ten standard parameters, so a link that also lumps fixed
//! children gets the change, not the lumped values.

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use toml_edit::{Array, InlineTable, Item, Table, Value};

use super::{number, set_keeping_decor, value_number};
use crate::diagnose::shape::point_mass;
use crate::diagnose::whole::about_com;

/// Standard parameters (`shape::point_mass` order) of a body given by its
/// mass, COM and inertia about the COM ([ixx, ixy, ixz, iyy, iyz, izz]).
pub(super) fn standard(mass: f64, com: [f64; 3], inertia: [f64; 6]) -> [f64; 10] {
    let mut p = point_mass(mass, &Vector3::from(com));
    let [ixx, ixy, ixz, iyy, iyz, izz] = inertia;
    for (k, v) in [(4, ixx), (5, ixy), (6, iyy), (7, ixz), (8, iyz), (9, izz)] {
        p[k] += v;
    }
    p
}

/// Adds `change` (standard parameters) to the body of the link `table`
/// describes and writes its mass, COM and inertia back.
pub(super) fn correct_whole(table: &mut Table, link: &str, change: &[f64; 10]) -> Result<()> {
    let mass = table.get("mass").and_then(number).unwrap_or(0.0);
    let com = match table.get("com").and_then(Item::as_array) {
        Some(a) if a.len() == 3 => std::array::from_fn(|k| a.get(k).and_then(value_number)),
        None => [Some(0.0); 3],
        Some(_) => bail!("link `{link}`: `com` must have 3 entries"),
    };
    let com = com.map(|c| c.unwrap_or(0.0));
    let own = standard(
        mass,
        com,
        inertia_of(table).with_context(|| format!("link `{link}`"))?,
    );
    let corrected: [f64; 10] = std::array::from_fn(|k| own[k] + change[k]);
    let (new_mass, new_com, new_inertia) = about_com(&corrected);
    if !new_mass.is_finite() || new_mass <= 0.0 {
        bail!("link `{link}`: the corrected mass {new_mass} kg is not positive");
    }
    set_keeping_decor(table, "mass", Value::from(new_mass));
    set_keeping_decor(
        table,
        "com",
        Value::Array(new_com.iter().copied().collect::<Array>()),
    );
    let mut inertia = InlineTable::new();
    let [ixx, ixy, ixz, iyy, iyz, izz] = new_inertia;
    for (key, v) in [
        ("ixx", ixx),
        ("iyy", iyy),
        ("izz", izz),
        ("ixy", ixy),
        ("ixz", ixz),
        ("iyz", iyz),
    ] {
        inertia.insert(key, v.into());
    }
    set_keeping_decor(table, "inertia", Value::InlineTable(inertia));
    Ok(())
}

/// The link's inertia about its COM as [ixx, ixy, ixz, iyy, iyz, izz]:
/// the table form (missing entries zero), the 3 x 3 matrix form, or none.
fn inertia_of(table: &Table) -> Result<[f64; 6]> {
    let Some(item) = table.get("inertia") else {
        return Ok([0.0; 6]);
    };
    if let Some(entries) = item.as_inline_table() {
        let get = |k: &str| entries.get(k).and_then(value_number).unwrap_or(0.0);
        return Ok(["ixx", "ixy", "ixz", "iyy", "iyz", "izz"].map(get));
    }
    if let Some(entries) = item.as_table() {
        let get = |k: &str| entries.get(k).and_then(number).unwrap_or(0.0);
        return Ok(["ixx", "ixy", "ixz", "iyy", "iyz", "izz"].map(get));
    }
    let rows = item
        .as_array()
        .context("`inertia` is neither a table nor a matrix")?;
    let at = |r: usize, c: usize| {
        rows.get(r)
            .and_then(Value::as_array)
            .and_then(|row| row.get(c))
            .and_then(value_number)
            .context("`inertia` must be a 3 x 3 matrix of numbers")
    };
    Ok([
        at(0, 0)?,
        at(0, 1)?,
        at(0, 2)?,
        at(1, 1)?,
        at(1, 2)?,
        at(2, 2)?,
    ])
}
