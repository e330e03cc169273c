//! The study's table and plot.

use std::fmt::Write;

use super::ModeResult;

/// The comparison as a text table.
pub fn table(rows: &[ModeResult]) -> String {
    let mut s = format!(
        "{:<20} {:>9} {:>8} {:>13} {:>9} {:>9} {:>9}  {:<20}  {:<6} note\n",
        "mode",
        "wall (s)",
        "speedup",
        "cycles",
        "err cyc",
        "err lines",
        "err J",
        "own estimate (1 SE)",
        "image"
    );
    for r in rows {
        let own = r.est_err.map_or("-".to_string(), |e| {
            format!(
                "±{:.1}/{:.1}/{:.1}%",
                e[0] * 100.0,
                e[1] * 100.0,
                e[2] * 100.0
            )
        });
        let _ = writeln!(
            s,
            "{:<20} {:>9.2} {:>7.1}x {:>13.0} {:>+8.1}% {:>+8.1}% {:>+8.1}%  {:<20}  {:<6} {}",
            r.mode,
            r.wall_s,
            r.speedup,
            r.cycles,
            r.err_cycles * 100.0,
            r.err_lines * 100.0,
            r.err_energy * 100.0,
            own,
            match r.image_identical {
                Some(true) => "same",
                Some(false) => "DIFF",
                None => "-",
            },
            r.note
        );
    }
    s
}

/// Speedup (log scale) against the absolute error in cycles, one point per mode.
pub fn plot(rows: &[ModeResult]) -> String {
    let (w, h, left, bottom, top, right) = (640.0, 400.0, 70.0, 50.0, 40.0, 160.0);
    let max_err = rows
        .iter()
        .map(|r| r.err_cycles.abs() * 100.0)
        .fold(1.0f64, f64::max);
    let max_sp = rows.iter().map(|r| r.speedup).fold(10.0f64, f64::max);
    let lmax = max_sp.log10().ceil().max(1.0);
    let (pw, ph) = (w - left - right, h - top - bottom);
    let x = |sp: f64| left + sp.max(1e-3).log10().clamp(-1.0, lmax) / lmax * pw;
    let y = |e: f64| top + ph - e / max_err * ph;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">Speed against error (cycles)</text>"#,
        left + pw / 2.0
    );
    let _ = writeln!(
        s,
        r#"<line x1="{left}" y1="{}" x2="{}" y2="{}" stroke="black"/><line x1="{left}" y1="{top}" x2="{left}" y2="{}" stroke="black"/>"#,
        top + ph,
        left + pw,
        top + ph,
        top + ph
    );
    for d in 0..=lmax as i32 {
        let sp = 10f64.powi(d);
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{sp}x</text>"#,
            x(sp),
            top + ph + 18.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">speedup over cycle mode (log)</text>"#,
        left + pw / 2.0,
        h - 10.0
    );
    for i in 0..=4 {
        let e = max_err * i as f64 / 4.0;
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="end">{e:.1}%</text>"#,
            left - 6.0,
            y(e) + 4.0
        );
    }
    for r in rows {
        let (px, py) = (x(r.speedup), y(r.err_cycles.abs() * 100.0));
        let _ = writeln!(
            s,
            r##"<circle cx="{px:.1}" cy="{py:.1}" r="5" fill="#4477aa"/><text x="{:.1}" y="{:.1}">{}</text>"##,
            px + 8.0,
            py + 4.0,
            r.mode
        );
    }
    s += "</svg>\n";
    s
}
