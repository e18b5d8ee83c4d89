//! The command-line syntax of `--lock` and `--attach`.

use std::fmt;
use std::str::FromStr;

/// A rigid payload fixed to `link`: mass (kg), centre of mass in the link
/// frame (m) and, optionally, the inertia about that centre of mass in link
/// axes (kg m^2, order ixx iyy izz ixy ixz iyz). Without an inertia it is a
/// point mass.
///
/// Syntax: `LINK:mass=KG[,com=X;Y;Z][,inertia=IXX;IYY;IZZ[;IXY;IXZ;IYZ]]`,
/// e.g. `END_EFFECTOR:mass=0.2018,com=0;0;0.05` (quote it in a shell).
#[derive(Debug, Clone, PartialEq)]
pub struct Attachment {
    pub link: String,
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: Option<[f64; 6]>,
}

/// Parses `--lock JOINT=POSITION` (rad for revolute, m for prismatic joints).
pub fn parse_lock(s: &str) -> Result<(String, f64), String> {
    let (joint, value) = s
        .rsplit_once('=')
        .ok_or_else(|| format!("expected JOINT=POSITION (rad or m), found '{s}'"))?;
    let joint = joint.trim();
    if joint.is_empty() {
        return Err(format!(
            "missing joint name in '{s}' (expected JOINT=POSITION)"
        ));
    }
    let value = parse_number(value, "position")?;
    Ok((joint.to_string(), value))
}

fn parse_number(text: &str, what: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{what} must be a finite number, found '{text}'")),
    }
}

fn parse_numbers(text: &str, what: &str) -> Result<Vec<f64>, String> {
    text.split(';').map(|v| parse_number(v, what)).collect()
}

impl FromStr for Attachment {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        const SYNTAX: &str = "LINK:mass=KG[,com=X;Y;Z][,inertia=IXX;IYY;IZZ[;IXY;IXZ;IYZ]]";
        // Split at the last ':' so namespaced link names (`a:b`) still work.
        let (link, fields) = s
            .rsplit_once(':')
            .ok_or_else(|| format!("expected {SYNTAX}, found '{s}'"))?;
        let link = link.trim();
        if link.is_empty() {
            return Err(format!("missing link name in '{s}' (expected {SYNTAX})"));
        }
        let (mut mass, mut com, mut inertia) = (None, None, None);
        for field in fields.split(',') {
            let (key, value) = field
                .split_once('=')
                .ok_or_else(|| format!("expected KEY=VALUE in '{field}' (syntax {SYNTAX})"))?;
            let duplicate = match key.trim() {
                "mass" => mass.replace(parse_number(value, "mass")?).is_some(),
                "com" => com.replace(parse_com(value)?).is_some(),
                "inertia" => inertia.replace(parse_inertia(value)?).is_some(),
                other => {
                    return Err(format!(
                        "unknown key '{other}' (expected mass, com or inertia)"
                    ));
                }
            };
            if duplicate {
                return Err(format!("key '{}' given twice in '{s}'", key.trim()));
            }
        }
        let mass = mass.ok_or_else(|| format!("missing mass=KG in '{s}'"))?;
        if mass <= 0.0 {
            return Err(format!("mass must be > 0 kg, found {mass}"));
        }
        Ok(Attachment {
            link: link.to_string(),
            mass,
            com: com.unwrap_or_default(),
            inertia,
        })
    }
}

fn parse_com(value: &str) -> Result<[f64; 3], String> {
    let v = parse_numbers(value, "com")?;
    <[f64; 3]>::try_from(v).map_err(|_| format!("com needs 3 numbers X;Y;Z (m), found '{value}'"))
}

fn parse_inertia(value: &str) -> Result<[f64; 6], String> {
    let v = parse_numbers(value, "inertia")?;
    let six = match v.as_slice() {
        [xx, yy, zz] => [*xx, *yy, *zz, 0.0, 0.0, 0.0],
        [xx, yy, zz, xy, xz, yz] => [*xx, *yy, *zz, *xy, *xz, *yz],
        _ => {
            return Err(format!(
                "inertia needs 3 (IXX;IYY;IZZ) or 6 (IXX;IYY;IZZ;IXY;IXZ;IYZ) numbers, found '{value}'"
            ));
        }
    };
    let moments = super::inertia::principal_moments(&six).ok_or_else(|| {
        format!("inertia '{value}' has no principal moments (entries too large?)")
    })?;
    if moments[0] <= 0.0 {
        return Err(format!(
            "inertia '{value}' is not positive definite (smallest principal moment {:e})",
            moments[0]
        ));
    }
    Ok(six)
}

impl fmt::Display for Attachment {
    /// The command-line syntax, so `to_string().parse()` round-trips.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:?}"))
                .collect::<Vec<_>>()
                .join(";")
        };
        write!(
            f,
            "{}:mass={:?},com={}",
            self.link,
            self.mass,
            join(&self.com)
        )?;
        if let Some(inertia) = &self.inertia {
            write!(f, ",inertia={}", join(inertia))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attachment_syntax() {
        let a: Attachment = "tool:mass=0.2018,com=0;0;0.05".parse().expect("valid");
        assert_eq!(
            (a.link.as_str(), a.mass, a.com, a.inertia),
            ("tool", 0.2018, [0.0, 0.0, 0.05], None)
        );
        assert_eq!(a.to_string().parse::<Attachment>(), Ok(a));
        let b: Attachment = "ns:tool:mass=1,inertia=1;2;2".parse().expect("valid");
        assert_eq!(
            (b.link.as_str(), b.com, b.inertia),
            ("ns:tool", [0.0; 3], Some([1.0, 2.0, 2.0, 0.0, 0.0, 0.0]))
        );
        let bad = [
            ("tool", "expected LINK:mass=KG"),
            (":mass=1", "missing link name"),
            ("tool:com=0;0;0", "missing mass=KG"),
            ("tool:mass=0", "mass must be > 0 kg"),
            ("tool:mass=x", "mass must be a finite number, found 'x'"),
            ("tool:mass=1,com=0;0", "com needs 3 numbers"),
            ("tool:mass=1,size=2", "unknown key 'size'"),
            ("tool:mass=1,mass=2", "key 'mass' given twice"),
            ("tool:mass=1,inertia=1;1", "inertia needs 3"),
            (
                "tool:mass=1,inertia=1;1;-1",
                "inertia '1;1;-1' is not positive definite",
            ),
            ("tool:mass=1;com=0;0;0", "mass must be a finite number"),
        ];
        for (text, expected) in bad {
            let message = text.parse::<Attachment>().expect_err(text);
            assert!(message.contains(expected), "{text}: {message}");
        }
    }

    #[test]
    fn lock_syntax() {
        assert_eq!(parse_lock("J3=0.5"), Ok(("J3".to_string(), 0.5)));
        assert_eq!(parse_lock(" J3 = -1e-1 "), Ok(("J3".to_string(), -0.1)));
        assert!(
            parse_lock("J3")
                .unwrap_err()
                .contains("expected JOINT=POSITION")
        );
        assert!(parse_lock("=1").unwrap_err().contains("missing joint name"));
        assert!(parse_lock("J3=inf").unwrap_err().contains("finite number"));
    }
}
