//! ISO 230-2 figures for the axis and per target, with the VDI/DGQ 3441
//! figures beside them and the definitions used.

use super::{Page, Section, note};
use crate::page::{escape, table};
use crate::units::{Units, angle};
use crate::{conformity, rounding};
use survey_processing::iso230::Iso230;
use survey_processing::vdi3441::{Vdi3441, vdi3441};

/// The axis figures: ISO 230-2 and VDI/DGQ 3441 side by side.
pub fn axis_section(iso: &Iso230, units: Units, u_deg: Option<f64>) -> String {
    let vdi = vdi3441(iso);
    let u = units.symbol();
    let rows: Vec<Vec<String>> = [
        ("A, accuracy", Some(iso.a), iso.a_up, iso.a_down),
        ("R, repeatability", Some(iso.r), iso.r_up, iso.r_down),
        ("E, systematic positional deviation", Some(iso.e), iso.e_up, iso.e_down),
        ("M, mean positional deviation", iso.m, None, None),
        ("B, reversal value", iso.b, None, None),
        ("B mean, mean reversal value", iso.b_mean, None, None),
    ]
    .into_iter()
    .map(|(name, all, up, down)| {
        let at_u = |v: Option<f64>| rounding::opt(units, v, u_deg);
        vec![name.to_string(), at_u(all), at_u(up), at_u(down)]
    })
    .collect();
    let mut html = table(
        "tbl-iso-axis",
        &["ISO 230-2", &format!("axis, {u}"), &format!("forward (↑), {u}"), &format!("reverse (↓), {u}")],
        &rows,
    );
    html += &format!(
        "<p class=\"note\">{} runs. Deviation x = actual − target; s with n − 1; R<sub>i</sub> = max(2s↑ + 2s↓ + \
         |B<sub>i</sub>|, 4s↑, 4s↓); A from the bands x̄ ± 2s (the 1997 and later editions).</p>\n",
        iso.runs
    );
    html += &vdi_table(&vdi, units, u_deg);
    html
}

fn vdi_table(v: &Vdi3441, units: Units, u_deg: Option<f64>) -> String {
    let u = units.symbol();
    let rows = vec![
        vec!["P, positional uncertainty".to_string(), rounding::num(units, v.p_deg, u_deg)],
        vec!["Pa, position deviation".to_string(), rounding::num(units, v.pa_deg, u_deg)],
        vec!["Ps, largest positional scatter".to_string(), rounding::num(units, v.ps_deg, u_deg)],
        vec!["U, largest reversal span".to_string(), rounding::opt(units, v.u_deg, u_deg)],
        vec!["Ū, mean reversal span".to_string(), rounding::opt(units, v.u_mean_deg, u_deg)],
    ];
    let mut html = table("tbl-vdi", &["VDI/DGQ 3441", &format!("axis, {u}")], &rows);
    html += "<p class=\"note\" id=\"vdi-definitions\">The VDI/DGQ 3441 figures are computed from the same per-target \
             statistics as ISO 230-2, with these definitions: x̄<sub>j</sub> = (x̄↑<sub>j</sub> + \
             x̄↓<sub>j</sub>)/2; U<sub>j</sub> = |x̄↑<sub>j</sub> − x̄↓<sub>j</sub>|; Ps<sub>j</sub> = 6 (s↑<sub>j</sub> \
             + s↓<sub>j</sub>)/2; Pa = max x̄<sub>j</sub> − min x̄<sub>j</sub>; P = max<sub>j</sub> [x̄<sub>j</sub> + \
             (U<sub>j</sub> + Ps<sub>j</sub>)/2] − min<sub>j</sub> [x̄<sub>j</sub> − (U<sub>j</sub> + \
             Ps<sub>j</sub>)/2]; U and Ps the largest over the targets. Measured one way, U is not defined and P \
             uses U<sub>j</sub> = 0. Note the ±3s of VDI 3441 against ISO 230-2's ±2s, and that VDI's U, a reversal span, \
             is not the expanded uncertainty U this certificate states.</p>\n";
    html
}

/// The per-target table: ISO 230-2 statistics and VDI's U and Ps per target.
pub fn targets_section(iso: &Iso230, units: Units) -> String {
    let vdi = vdi3441(iso);
    let u = units.symbol();
    let rows: Vec<Vec<String>> = iso
        .targets
        .iter()
        .zip(&vdi.targets)
        .map(|(t, v)| {
            let d = |x: Option<&survey_processing::iso230::DirStats>,
                     f: fn(&survey_processing::iso230::DirStats) -> f64| { units.opt(x.map(f)) };
            vec![
                angle(t.target_deg),
                d(t.up.as_ref(), |s| s.mean),
                d(t.up.as_ref(), |s| s.s),
                d(t.down.as_ref(), |s| s.mean),
                d(t.down.as_ref(), |s| s.s),
                units.opt(t.b),
                units.num(t.r),
                units.opt(t.mean_bi),
                units.opt(v.u_deg),
                units.num(v.ps_deg),
            ]
        })
        .collect();
    let head = [
        "target, deg".to_string(),
        format!("x̄↑, {u}"),
        format!("s↑, {u}"),
        format!("x̄↓, {u}"),
        format!("s↓, {u}"),
        format!("B<sub>i</sub>, {u}"),
        format!("R<sub>i</sub>, {u}"),
        format!("x̄<sub>i</sub>, {u}"),
        format!("U<sub>j</sub>, {u}"),
        format!("Ps<sub>j</sub>, {u}"),
    ];
    let head: Vec<&str> = head.iter().map(String::as_str).collect();
    let mut html = format!(
        "<p class=\"note\">Per target: mean deviation x̄ = mean(actual − target) and its standard deviation s over the \
         runs, forward (↑) and reverse (↓); {} targets.</p>\n",
        iso.targets.len()
    );
    html += &table("tbl-iso-targets", &head, &rows);
    html += &format!(
        "<p class=\"note\">{}</p>\n",
        escape("B_i = x̄↑ − x̄↓; x̄_i = (x̄↑ + x̄↓)/2; R_i as above; U_j and Ps_j as in VDI/DGQ 3441 above.")
    );
    html
}

/// The axis figures, or why there are none.
pub fn show_axis(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let body = match &p.iso {
        Ok(iso) => {
            let reference_u = p.cert.reference_uncertainty_deg.as_ref().map(|u| u.value);
            let measured_u = conformity::accuracy_u_deg(reference_u, p.d.reference_systematic_u_deg, p.d.axis_u_deg);
            let u = match measured_u {
                Some(u) => format!(
                    "The measured figures A, E and M carry the expanded uncertainty U = {} (k = 2) of the \
                     measurement (see the summary).",
                    crate::rounding::show_u(p.units, u)
                ),
                None => "The reference's uncertainty is not stated: the figures' uncertainty is not known.".into(),
            };
            axis_section(iso, p.units, measured_u) + &note(&u)
        }
        Err(e) => note(&format!("No ISO 230-2 figures: {e}.")),
    };
    Ok(Section::page("iso230", "ISO 230-2 and VDI/DGQ 3441", body))
}

/// The per-target table, an appendix.
pub fn show_targets(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    Ok(p.iso
        .as_ref()
        .ok()
        .and_then(|iso| Section::page("iso230-targets", "ISO 230-2 per target", targets_section(iso, p.units))))
}
