//! A minimal SVG line plot (no plotting dependency, no fonts to ship).

use std::fmt::Write;

/// One named series of `(x, y)` points; non-finite points break the line.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// Axis settings.
pub struct Axes<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub log_x: bool,
}

const PALETTE: [&str; 10] =
    ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];

/// Renders the series as an SVG document (800 x 500 px, legend on the right).
pub fn line_plot(axes: &Axes<'_>, series: &[Series]) -> String {
    let (w, h, left, right, top, bottom) = (800.0, 500.0, 70.0, 210.0, 40.0, 60.0);
    let tx = |x: f64| if axes.log_x { x.log10() } else { x };
    let finite: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|(x, y)| tx(*x).is_finite() && y.is_finite())
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for (x, y) in &finite {
        x0 = x0.min(tx(*x));
        x1 = x1.max(tx(*x));
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if finite.is_empty() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1 - x0 < 1e-12 {
        x1 = x0 + 1.0;
    }
    let pad = ((y1 - y0) * 0.05).max(1e-12);
    (y0, y1) = (y0 - pad, y1 + pad);
    let px = |x: f64| left + (tx(x) - x0) / (x1 - x0) * (w - left - right);
    let py = |y: f64| top + (y1 - y) / (y1 - y0) * (h - top - bottom);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#,
        (left + w - right) / 2.0,
        esc(axes.title)
    );
    let (pl, pr, pt, pb) = (left, w - right, top, h - bottom);
    let _ =
        writeln!(s, r#"<rect x="{pl}" y="{pt}" width="{}" height="{}" fill="none" stroke="black"/>"#, pr - pl, pb - pt);
    // Ticks: 5 on y; decades (log) or 5 on x.
    for k in 0..=5 {
        let y = y0 + (y1 - y0) * k as f64 / 5.0;
        let _ = writeln!(s, r##"<line x1="{pl}" x2="{pr}" y1="{0:.1}" y2="{0:.1}" stroke="#ddd"/>"##, py(y));
        let _ = writeln!(s, r#"<text x="{}" y="{:.1}" text-anchor="end">{}</text>"#, pl - 6.0, py(y) + 4.0, fmt_num(y));
    }
    let x_ticks: Vec<f64> = if axes.log_x {
        (x0.floor() as i32..=x1.ceil() as i32)
            .map(|e| 10f64.powi(e))
            .filter(|v| tx(*v) >= x0 - 1e-9 && tx(*v) <= x1 + 1e-9)
            .collect()
    } else {
        (0..=5).map(|k| x0 + (x1 - x0) * k as f64 / 5.0).collect()
    };
    for x in x_ticks {
        let _ = writeln!(s, r##"<line x1="{0:.1}" x2="{0:.1}" y1="{pt}" y2="{pb}" stroke="#ddd"/>"##, px(x));
        let _ = writeln!(s, r#"<text x="{:.1}" y="{}" text-anchor="middle">{}</text>"#, px(x), pb + 16.0, fmt_num(x));
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        (pl + pr) / 2.0,
        h - 18.0,
        esc(axes.x_label)
    );
    let _ = writeln!(
        s,
        r#"<text x="16" y="{0}" text-anchor="middle" transform="rotate(-90 16 {0})">{1}</text>"#,
        (pt + pb) / 2.0,
        esc(axes.y_label)
    );
    for (k, ser) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let mut path = String::new();
        let mut pen_down = false;
        for &(x, y) in &ser.points {
            if tx(x).is_finite() && y.is_finite() {
                let _ = write!(path, "{}{:.1},{:.1} ", if pen_down { "L" } else { "M" }, px(x), py(y));
                let _ = writeln!(s, r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{color}"/>"#, px(x), py(y));
                pen_down = true;
            } else {
                pen_down = false;
            }
        }
        let _ = writeln!(s, r#"<path d="{path}" fill="none" stroke="{color}" stroke-width="1.5"/>"#);
        let ly = pt + 14.0 + 18.0 * k as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{}" x2="{}" y1="{ly}" y2="{ly}" stroke="{color}" stroke-width="2"/>"#,
            pr + 12.0,
            pr + 32.0
        );
        let _ = writeln!(s, r#"<text x="{}" y="{}">{}</text>"#, pr + 38.0, ly + 4.0, esc(&ser.name));
    }
    s.push_str("</svg>\n");
    s
}

fn fmt_num(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) {
        format!("{v:.0e}")
    } else {
        format!("{}", (v * 1000.0).round() / 1000.0)
    }
}

fn esc(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}
