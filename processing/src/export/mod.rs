//! Table files as bytes: pure writers, no file system (the caller stages and
//! renames them into place).
//!
//! - [`table_csv`]: the contract's correction table. Header `readout_deg,error_deg`
//!   (or `readout_deg,error_forward_deg,error_reverse_deg`), one row per table
//!   row at `360 i / n` degrees from 0 up to `360 - 360/n`, numbers in Rust's
//!   shortest round-trip form.
//! - [`linuxcnc`]: LinuxCNC joint compensation files, for `[JOINT_n] COMP_FILE = ...`
//!   with `COMP_FILE_TYPE = 0` and `1`. Looked up in LinuxCNC's source
//!   (LinuxCNC/linuxcnc: `src/emc/ini/inijoint.cc` reads `COMP_FILE_TYPE`,
//!   default 0; `usrmotLoadComp` in `src/emc/motion/usrmotintf.cc` reads one
//!   `nominal forward reverse` triplet per line with `sscanf("%lf %lf %lf")`
//!   and stops at the first line that is not one, so there is no header line;
//!   type 0 holds positions and is turned into trims as `nominal - forward`,
//!   type 1 holds the trims `forward_trim reverse_trim` directly;
//!   `EMCMOT_SET_JOINT_COMP` in `command.c` refuses more than
//!   `EMCMOT_COMP_SIZE` = 256 entries and nominals that do not increase; and
//!   `control.c` adds the forward trim to the motor command while moving up,
//!   the reverse trim while moving down, interpolating linearly between
//!   entries). The motor position is our readout and the trim that puts the
//!   axis on the commanded angle is our error `readout - actual`, so a line is
//!   `nominal  nominal-error_fwd  nominal-error_rev` (type 0: the actual
//!   angles the axis reaches) or `nominal  error_fwd  error_rev` (type 1),
//!   ascending nominals, at most 256 lines, 10 decimals.
//! - The binary table is [`crate::corrector::to_bytes`].

use crate::pipeline::CompTable;
use crate::table::CorrectionTable;
use std::fmt::Write as _;

/// The contract's table CSV.
pub fn table_csv(table: &CorrectionTable) -> String {
    let mut s = String::with_capacity(table.len() * 48);
    match &table.reverse {
        None => {
            s.push_str("readout_deg,error_deg\n");
            for (i, e) in table.forward.iter().enumerate() {
                let _ = writeln!(s, "{},{e}", table.readout_at(i));
            }
        }
        Some(r) => {
            s.push_str("readout_deg,error_forward_deg,error_reverse_deg\n");
            for (i, (f, r)) in table.forward.iter().zip(r).enumerate() {
                let _ = writeln!(s, "{},{f},{r}", table.readout_at(i));
            }
        }
    }
    s
}

/// A LinuxCNC `COMP_FILE` of `COMP_FILE_TYPE` 0 (positions) or 1 (trims).
pub fn linuxcnc(comp: &CompTable, file_type: u8) -> String {
    let mut s = String::with_capacity(comp.nominal_deg.len() * 48);
    for ((n, f), r) in comp.nominal_deg.iter().zip(&comp.forward_deg).zip(&comp.reverse_deg) {
        let (a, b) = if file_type == 0 { (n - f, n - r) } else { (*f, *r) };
        let _ = writeln!(s, "{n:.10} {a:.10} {b:.10}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_and_linuxcnc_formats() {
        let t =
            CorrectionTable::directional(vec![0.001, 0.002, 0.003, 0.004], vec![-0.001, 0.0, 0.001, 0.002]).unwrap();
        assert_eq!(
            table_csv(&t),
            "readout_deg,error_forward_deg,error_reverse_deg\n0,0.001,-0.001\n90,0.002,0\n180,0.003,0.001\n270,0.004,0.002\n"
        );
        let one = CorrectionTable::new(vec![0.5, -0.25]).unwrap();
        assert_eq!(table_csv(&one), "readout_deg,error_deg\n0,0.5\n180,-0.25\n");
        let comp = CompTable {
            nominal_deg: vec![0.0, 180.0, 360.0],
            forward_deg: vec![0.001, 0.002, 0.001],
            reverse_deg: vec![-0.001, 0.0, -0.001],
            prediction: None,
        };
        assert_eq!(
            linuxcnc(&comp, 0),
            "0.0000000000 -0.0010000000 0.0010000000\n180.0000000000 179.9980000000 180.0000000000\n360.0000000000 359.9990000000 360.0010000000\n"
        );
        assert_eq!(linuxcnc(&comp, 1).lines().next(), Some("0.0000000000 0.0010000000 -0.0010000000"));
    }
}
