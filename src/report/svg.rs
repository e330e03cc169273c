//! Minimal SVG bar charts (no plotting dependency): grouped bars of ours against
//! the paper's figures, like the paper's Figures 7 (ray duplication) and 8
//! (memory traffic per stream).

use std::fmt::Write;

/// One group of bars (a scene) with one value per series.
pub struct Group {
    pub label: String,
    pub values: Vec<f64>,
}

/// A grouped bar chart; `series` names each bar of a group.
pub fn grouped_bars(title: &str, unit: &str, series: &[&str], groups: &[Group]) -> String {
    let (w, h, left, bottom, top) = (720.0, 360.0, 60.0, 60.0, 40.0);
    let max = groups
        .iter()
        .flat_map(|g| g.values.iter().copied())
        .fold(0.0f64, f64::max)
        .max(1e-12);
    let plot_h = h - bottom - top;
    let gw = (w - left - 20.0) / groups.len().max(1) as f64;
    let bw = gw * 0.8 / series.len().max(1) as f64;
    let colors = [
        "#4477aa", "#ee6677", "#228833", "#ccbb44", "#66ccee", "#aa3377",
    ];
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#,
        w / 2.0,
        esc(title)
    );
    let _ = writeln!(
        s,
        r#"<line x1="{left}" y1="{}" x2="{}" y2="{}" stroke="black"/>"#,
        h - bottom,
        w - 20.0,
        h - bottom
    );
    let _ = writeln!(
        s,
        r#"<line x1="{left}" y1="{top}" x2="{left}" y2="{}" stroke="black"/>"#,
        h - bottom
    );
    for k in 0..=4 {
        let v = max * k as f64 / 4.0;
        let y = h - bottom - plot_h * k as f64 / 4.0;
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="end">{}</text>"#,
            left - 6.0,
            y + 4.0,
            fmt(v)
        );
        let _ = writeln!(
            s,
            r##"<line x1="{left}" y1="{y}" x2="{}" y2="{y}" stroke="#dddddd"/>"##,
            w - 20.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="14" y="{}" transform="rotate(-90 14 {})" text-anchor="middle">{}</text>"#,
        top + plot_h / 2.0,
        top + plot_h / 2.0,
        esc(unit)
    );
    for (gi, g) in groups.iter().enumerate() {
        let x0 = left + gi as f64 * gw + gw * 0.1;
        for (si, v) in g.values.iter().enumerate() {
            let bh = plot_h * v / max;
            let x = x0 + si as f64 * bw;
            let _ = writeln!(
                s,
                r#"<rect x="{x:.1}" y="{:.1}" width="{:.1}" height="{bh:.1}" fill="{}"><title>{}: {}</title></rect>"#,
                h - bottom - bh,
                bw * 0.95,
                colors[si % colors.len()],
                esc(series.get(si).copied().unwrap_or("")),
                fmt(*v)
            );
        }
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{}" text-anchor="middle">{}</text>"#,
            x0 + gw * 0.4,
            h - bottom + 18.0,
            esc(&g.label)
        );
    }
    for (si, name) in series.iter().enumerate() {
        let x = left + 10.0 + si as f64 * 150.0;
        let _ = writeln!(
            s,
            r#"<rect x="{x}" y="{}" width="12" height="12" fill="{}"/>"#,
            h - 22.0,
            colors[si % colors.len()]
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}">{}</text>"#,
            x + 16.0,
            h - 12.0,
            esc(name)
        );
    }
    s.push_str("</svg>\n");
    s
}

fn fmt(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else if v >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

fn esc(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bars_scale_to_the_largest_value() {
        let g = vec![
            Group {
                label: "A".into(),
                values: vec![1.0, 2.0],
            },
            Group {
                label: "B & C".into(),
                values: vec![4.0, 0.5],
            },
        ];
        let s = grouped_bars("t", "u", &["ours", "paper"], &g);
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        assert_eq!(
            s.matches("<rect x=").count(),
            4 + 2,
            "4 bars and 2 legend boxes"
        );
        // The largest bar fills the plot height (360 - 60 - 40 = 260).
        assert!(s.contains(r##"height="260.0" fill="#"##), "{s}");
        assert!(s.contains("B &amp; C"));
    }
}
