//! The machine's frame in the tracker's (`[machine_frame]` of a
//! configuration or a model file): where the axis's location (ISO 230-1)
//! is stated beside the tracker's frame.
//!
//! `origin_mm = [x, y, z]`: the machine's origin in the tracker's frame, mm.
//! `rotation_deg = [rx, ry, rz]` (default 0): the machine's axes in the
//! tracker's frame, as rotations about the tracker's fixed x, then y, then z
//! axes (right-handed; "fixed XYZ", as alignment software such as
//! SpatialAnalyzer reports a transform): `R = Rz(rz) Ry(ry) Rx(rx)`, whose
//! columns are the machine's x, y and z axes in tracker coordinates. A
//! point `p` of the tracker's frame is `R^T (p - origin)` in the machine's.
//!
//! The alignment's own uncertainty, where it states one (both optional):
//! `origin_u_mm`, the expanded uncertainty (k = 2) of each coordinate of
//! `origin_mm`; `rotation_u_deg`, of each of the three rotations. The
//! location in the machine's frame carries what they make of it beside the
//! fit's (`survey_motions::MachineLocation`).

/// The machine's frame in the tracker's (see the module documentation).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineFrame {
    pub origin_mm: [f64; 3],
    #[serde(default)]
    pub rotation_deg: [f64; 3],
    /// `U` (k = 2) of each coordinate of `origin_mm`, as the alignment states it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin_u_mm: Option<f64>,
    /// `U` (k = 2) of each of the rotations, as the alignment states it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_u_deg: Option<f64>,
}

/// The largest origin coordinate, mm (a tracker measures to some 80 m).
pub const MAX_ORIGIN_MM: f64 = 100_000.0;

/// The largest `origin_u_mm`, mm: an alignment worse than this does not
/// locate an axis.
pub const MAX_ORIGIN_U_MM: f64 = 100.0;

/// The largest `rotation_u_deg`, deg.
pub const MAX_ROTATION_U_DEG: f64 = 10.0;

/// The keys of `[machine_frame]`.
pub const KEYS: [&str; 4] = ["origin_mm", "rotation_deg", "origin_u_mm", "rotation_u_deg"];

impl MachineFrame {
    /// `R`: its columns the machine's axes in tracker coordinates.
    pub fn rotation(&self) -> [[f64; 3]; 3] {
        let [(sx, cx), (sy, cy), (sz, cz)] = self.rotation_deg.map(|d| d.to_radians().sin_cos());
        [
            [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
            [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
            [-sy, cy * sx, cy * cx],
        ]
    }

    /// A direction of the tracker's frame in the machine's: `R^T d`.
    pub fn direction(&self, d: [f64; 3]) -> [f64; 3] {
        let r = self.rotation();
        std::array::from_fn(|j| (0..3).map(|i| r[i][j] * d[i]).sum())
    }

    /// A point of the tracker's frame in the machine's: `R^T (p - origin)`.
    pub fn point(&self, p: [f64; 3]) -> [f64; 3] {
        self.direction(std::array::from_fn(|i| p[i] - self.origin_mm[i]))
    }

    /// The section as a file writes it.
    pub fn section_toml(&self) -> String {
        // Rust's shortest form of a float reads back to the same bits.
        let list = |v: [f64; 3]| v.map(|x| format!("{x}")).join(", ");
        let mut s = format!(
            "[machine_frame]\norigin_mm = [{}]\nrotation_deg = [{}]\n",
            list(self.origin_mm),
            list(self.rotation_deg)
        );
        for (key, u) in [("origin_u_mm", self.origin_u_mm), ("rotation_u_deg", self.rotation_u_deg)] {
            if let Some(u) = u {
                // A whole number written as a float, so it reads back as one.
                s += &format!("{key} = {u:?}\n");
            }
        }
        s
    }
}

/// Parse a `[machine_frame]` table named `section`; `at(key)` is the line of
/// a key.
pub fn parse_section(
    t: &toml::Table,
    section: &str,
    at: &dyn Fn(&str) -> Option<usize>,
) -> Result<MachineFrame, (Option<usize>, String)> {
    if let Some(k) = t.keys().find(|k| !KEYS.contains(&k.as_str())) {
        return Err((at(k), format!("{section}: unknown key '{k}' (expected {})", KEYS.join(", "))));
    }
    let u = |key: &str, limit: f64, unit: &str, what: &str| -> Result<Option<f64>, (Option<usize>, String)> {
        let Some(v) = t.get(key) else { return Ok(None) };
        match v {
            toml::Value::Float(f) if f.is_finite() && (0.0..=limit).contains(f) => Ok(Some(*f)),
            toml::Value::Integer(i) if (0..=limit as i64).contains(i) => Ok(Some(*i as f64)),
            _ => Err((
                at(key),
                format!(
                    "{section}.{key} must be a number from 0 to {limit} {unit}: the expanded uncertainty (k = 2) of \
                     {what} as the alignment states it"
                ),
            )),
        }
    };
    let origin_u_mm = u("origin_u_mm", MAX_ORIGIN_U_MM, "mm", "each coordinate of origin_mm")?;
    let rotation_u_deg = u("rotation_u_deg", MAX_ROTATION_U_DEG, "deg", "each of rotation_deg's rotations")?;
    let three = |key: &str, limit: f64, unit: &str| -> Result<Option<[f64; 3]>, (Option<usize>, String)> {
        let Some(v) = t.get(key) else { return Ok(None) };
        let bad =
            || (at(key), format!("{section}.{key} must be three numbers [x, y, z], each within +/-{limit} {unit}"));
        let arr = v.as_array().filter(|a| a.len() == 3).ok_or_else(bad)?;
        let mut out = [0.0; 3];
        for (o, x) in out.iter_mut().zip(arr) {
            *o = match x {
                toml::Value::Float(f) if f.is_finite() && f.abs() <= limit => *f,
                toml::Value::Integer(i) if (*i as f64).abs() <= limit => *i as f64,
                _ => return Err(bad()),
            };
        }
        Ok(Some(out))
    };
    let origin_mm = three("origin_mm", MAX_ORIGIN_MM, "mm")?.ok_or((
        None,
        format!("{section}: missing key 'origin_mm' (the machine's origin in the tracker's frame, mm)"),
    ))?;
    let rotation_deg = three("rotation_deg", 360.0, "deg")?.unwrap_or_default();
    Ok(MachineFrame { origin_mm, rotation_deg, origin_u_mm, rotation_u_deg })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rotation_is_fixed_xyz_and_the_transform_inverts_it() {
        // 90 deg about z: the machine's x is the tracker's y.
        let f = MachineFrame { origin_mm: [1.0, 2.0, 3.0], rotation_deg: [0.0, 0.0, 90.0], ..Default::default() };
        let p = f.point([1.0, 3.0, 3.0]);
        assert!((p[0] - 1.0).abs() < 1e-12 && p[1].abs() < 1e-12 && p[2].abs() < 1e-12, "{p:?}");
        // x first, then y, about the fixed axes: R ez = Ry(ry) Rx(rx) ez = (sin ry cos rx, -sin rx, cos ry cos rx).
        let f = MachineFrame { origin_mm: [0.0; 3], rotation_deg: [10.0, 20.0, 0.0], ..Default::default() };
        let r = f.rotation();
        let (rx, ry) = (10f64.to_radians(), 20f64.to_radians());
        let z = [ry.sin() * rx.cos(), -rx.sin(), ry.cos() * rx.cos()];
        assert!((0..3).all(|i| (r[i][2] - z[i]).abs() < 1e-12), "{r:?}");
        assert!(f.direction(z).iter().zip([0.0, 0.0, 1.0]).all(|(a, b)| (a - b).abs() < 1e-12));
    }

    #[test]
    fn a_model_file_states_it_and_a_bad_one_is_named_with_its_line() {
        use crate::model::Model;
        let text = "[machine_frame]\norigin_mm = [2500, 800, -300.5]\nrotation_deg = [0.1, -0.2, 30]\n";
        let m = Model::parse(text, "m.toml").unwrap();
        let f = m.machine_frame.unwrap();
        assert_eq!((f.origin_mm, f.rotation_deg), ([2500.0, 800.0, -300.5], [0.1, -0.2, 30.0]));
        assert_eq!(Model::parse(&m.to_toml(), "again").unwrap(), m);
        let only = Model::parse("[machine_frame]\norigin_mm = [1, 2, 3]\n", "m.toml").unwrap();
        assert_eq!(only.machine_frame.unwrap().rotation_deg, [0.0; 3]);
        assert_eq!((f.origin_u_mm, f.rotation_u_deg, only.machine_frame.unwrap().origin_u_mm), (None, None, None));
        // The alignment's uncertainty, stated: read, and written back.
        let text = "[machine_frame]\norigin_mm = [1, 2, 3]\norigin_u_mm = 0.05\nrotation_u_deg = 1\n";
        let m = Model::parse(text, "m.toml").unwrap();
        let f = m.machine_frame.unwrap();
        assert_eq!((f.origin_u_mm, f.rotation_u_deg), (Some(0.05), Some(1.0)));
        assert_eq!(Model::parse(&m.to_toml(), "again").unwrap(), m);
        for (bad, line, says) in [
            ("[machine_frame]\norigin_mm = [1, 2]\n", 2, "machine_frame.origin_mm must be three numbers"),
            ("[machine_frame]\norigin_mm = [1, 2, 3]\nrotation_deg = [0, 400, 0]\n", 3, "within +/-360 deg"),
            ("[machine_frame]\norigin_mm = [1, 2, 3]\nrotate = [0, 0, 0]\n", 3, "unknown key 'rotate'"),
            ("[machine_frame]\nrotation_deg = [0, 0, 0]\n", 1, "missing key 'origin_mm'"),
            ("[machine_frame]\norigin_mm = [1, \"x\", 3]\n", 2, "three numbers"),
            ("[machine_frame]\norigin_mm = [1, 2, 3]\norigin_u_mm = -0.1\n", 3, "origin_u_mm must be a number from 0"),
            ("[machine_frame]\norigin_mm = [1, 2, 3]\nrotation_u_deg = [1, 2, 3]\n", 3, "rotation_u_deg must be"),
            ("[machine_frame]\norigin_mm = [1, 2, 3]\nrotation_u_deg = 11\n", 3, "from 0 to 10 deg"),
        ] {
            let e = Model::parse(bad, "bad.toml").unwrap_err();
            assert_eq!(e.line, Some(line), "{bad}: {e}");
            assert!(e.message.contains(says), "{bad}: {e}");
        }
    }
}
