//! The telemetry stream: a run log (docs/interfaces.md section 1) written
//! row by row on the console.

use core::fmt::Write;

use crate::text::Buf;

/// The run-log header the telemetry stream starts with (docs/interfaces.md section
/// 1), for `controller`; CR LF line ends.
pub fn write_log_header<W: Write>(out: &mut W, controller: &str) {
    let _ = out.write_str("# dca-log v1\r\n# controller=");
    let _ = out.write_str(controller);
    let _ = out.write_str("\r\n# source=dca-firmware telemetry\r\n");
    let _ = out.write_str("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,state,faults\r\n");
}

/// One telemetry row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LogRow {
    /// Row index since the stream started.
    pub n: u32,
    /// Time between rows, ms.
    pub step_ms: u32,
    /// Reference, m.
    pub ref_m: f32,
    /// Drive command, m/s.
    pub v_cmd_mps: f32,
    /// The sample.
    pub sample: dca_core::controller::Sample,
    /// Supervisor state.
    pub state: u8,
    /// Latched faults.
    pub faults: u16,
}

/// Format one run-log row (the columns of [`write_log_header`]), CR LF ended.
/// Time is `n * step_ms` exactly, printed with 3 decimals.
pub fn write_log_row<const N: usize>(out: &mut Buf<N>, row: &LogRow) {
    let t_ms = row.n as u64 * row.step_ms as u64;
    let (s, ms) = crate::text::div_rem(t_ms, 1000);
    out.push_u64(s);
    out.push_byte(b'.');
    out.push_byte(b'0' + (ms / 100) as u8);
    out.push_byte(b'0' + (ms / 10 % 10) as u8);
    out.push_byte(b'0' + (ms % 10) as u8);
    let s = &row.sample;
    for (v, d) in [
        (row.ref_m, 7),
        (row.v_cmd_mps, 7),
        (s.xi_m, 8),
        (s.xo_m, 8),
        (s.p1_pa, 1),
        (s.p2_pa, 1),
        (s.ft_n, 2),
    ] {
        out.push_byte(b',');
        out.push_fixed(v as f64, d);
    }
    out.push_byte(b',');
    out.push_u64(row.state as u64);
    out.push_byte(b',');
    out.push_u64(row.faults as u64);
    out.push_str("\r\n");
}
