//! Line charts as SVG (plotters' SVG backend: no fonts or system libraries needed), the one
//! drawing routine every bench chart goes through.

use crate::error::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A solid line through the points, with a dot at each.
    Line,
    /// A dashed line (predictions, references).
    Dashed,
    /// Dots only.
    Points,
}

/// One named curve.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
    /// Index into the palette; series with the same colour belong together.
    pub colour: usize,
    /// Text written next to chosen points (x, y, text), e.g. iterations fitting a budget.
    pub notes: Vec<(f64, f64, String)>,
}

impl Series {
    pub fn new(
        name: impl Into<String>,
        points: Vec<(f64, f64)>,
        style: Style,
        colour: usize,
    ) -> Series {
        Series {
            name: name.into(),
            points,
            style,
            colour,
            notes: Vec::new(),
        }
    }
}

/// A chart: axes, series and vertical guide lines (e.g. time budgets).
#[derive(Clone, Debug, Default)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x_log: bool,
    pub y_log: bool,
    pub series: Vec<Series>,
    /// Vertical lines at x with a label.
    pub guides: Vec<(f64, String)>,
    /// Legend in the lower left corner instead of the upper right (for curves that fall to the
    /// right).
    pub legend_lower_left: bool,
}

/// An axis label: three significant digits, in scientific notation outside [0.01, 10⁵).
fn tick(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if (0.01..1e5).contains(&a) {
        let digits = (2 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.2e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        format!("{mantissa}e{exponent}")
    }
}

const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

impl Chart {
    /// Writes the chart to `path` as a 900 × 600 SVG (see [`Chart::to_svg`]).
    pub fn write_svg(&self, path: &Path) -> Result<()> {
        let svg = self
            .to_svg()
            .map_err(|reason| Error::io(path, "cannot draw", std::io::Error::other(reason)))?;
        write_atomically(path, svg.as_bytes())
    }

    /// The chart as a 900 × 600 SVG document. Points that a log axis cannot show (zero,
    /// negative, not finite) are left out; a chart with no point to show is an error.
    // Long: plotters gives each of the four axis combinations its own coordinate type, so one
    // macro body draws all four; split, it would repeat those generics.
    pub fn to_svg(&self) -> std::result::Result<String, String> {
        let fail = |e: &dyn std::fmt::Display| e.to_string();
        let shown = |x: f64, log: bool| x.is_finite() && (!log || x > 0.0);
        let visible: Vec<Vec<(f64, f64)>> = self
            .series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .copied()
                    .filter(|&(x, y)| shown(x, self.x_log) && shown(y, self.y_log))
                    .collect()
            })
            .collect();
        let all = visible.iter().flatten();
        let (mut x0, mut x1, y0, y1) = all.fold(
            (f64::MAX, f64::MIN, f64::MAX, f64::MIN),
            |(a, b, c, d), &(x, y)| (a.min(x), b.max(x), c.min(y), d.max(y)),
        );
        for (x, _) in &self.guides {
            x0 = x0.min(*x);
            x1 = x1.max(*x);
        }
        if x0 > x1 || y0 > y1 {
            return Err(fail(&format!(
                "chart '{}' has no points to draw",
                self.title
            )));
        }
        let pad = |lo: f64, hi: f64, log: bool| {
            if log {
                (lo / 1.3, hi * 1.3)
            } else if hi > lo {
                let m = 0.05 * (hi - lo);
                (lo - m, hi + m)
            } else {
                (lo - 1.0, hi + 1.0)
            }
        };
        let (x0, x1) = pad(x0, x1, self.x_log);
        let (y0, y1) = pad(y0, y1, self.y_log);
        let mut svg = String::new();
        let root = SVGBackend::with_string(&mut svg, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(&self.title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70);
        // The four axis combinations are four coordinate types; one generic body draws them.
        macro_rules! draw {
            ($xr:expr, $yr:expr) => {{
                let mut chart = builder.build_cartesian_2d($xr, $yr).map_err(|e| fail(&e))?;
                chart
                    .configure_mesh()
                    .x_desc(self.x_label.as_str())
                    .y_desc(self.y_label.as_str())
                    .x_label_formatter(&|v| tick(*v))
                    .y_label_formatter(&|v| tick(*v))
                    .draw()
                    .map_err(|e| fail(&e))?;
                for (x, label) in &self.guides {
                    let grey = RGBColor(160, 160, 160);
                    chart
                        .draw_series(std::iter::once(PathElement::new(
                            vec![(*x, y0), (*x, y1)],
                            grey.stroke_width(1),
                        )))
                        .map_err(|e| fail(&e))?;
                    chart
                        .draw_series(std::iter::once(Text::new(
                            label.clone(),
                            (*x, y1),
                            ("sans-serif", 13).into_font().color(&grey),
                        )))
                        .map_err(|e| fail(&e))?;
                }
                for (s, points) in self.series.iter().zip(&visible) {
                    let colour = PALETTE[s.colour % PALETTE.len()];
                    let style = colour.stroke_width(2);
                    match s.style {
                        Style::Line => {
                            chart
                                .draw_series(LineSeries::new(points.clone(), style))
                                .map_err(|e| fail(&e))?
                                .label(s.name.as_str())
                                .legend(move |(x, y)| {
                                    PathElement::new(vec![(x, y), (x + 20, y)], style)
                                });
                            if points.len() <= 40 {
                                chart
                                    .draw_series(
                                        points.iter().map(|&p| Circle::new(p, 3, colour.filled())),
                                    )
                                    .map_err(|e| fail(&e))?;
                            }
                        }
                        Style::Dashed => {
                            chart
                                .draw_series(DashedLineSeries::new(points.clone(), 8, 5, style))
                                .map_err(|e| fail(&e))?
                                .label(s.name.as_str())
                                .legend(move |(x, y)| {
                                    PathElement::new(
                                        vec![(x, y), (x + 20, y)],
                                        colour.stroke_width(1),
                                    )
                                });
                        }
                        Style::Points => {
                            chart
                                .draw_series(
                                    points.iter().map(|&p| Circle::new(p, 4, colour.filled())),
                                )
                                .map_err(|e| fail(&e))?
                                .label(s.name.as_str())
                                .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
                        }
                    }
                    for (x, y, text) in &s.notes {
                        if shown(*x, self.x_log) && shown(*y, self.y_log) {
                            chart
                                .draw_series(std::iter::once(Text::new(
                                    text.clone(),
                                    (*x, *y),
                                    ("sans-serif", 12).into_font().color(&colour),
                                )))
                                .map_err(|e| fail(&e))?;
                        }
                    }
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .position(if self.legend_lower_left {
                        SeriesLabelPosition::LowerLeft
                    } else {
                        SeriesLabelPosition::UpperRight
                    })
                    .draw()
                    .map_err(|e| fail(&e))?;
            }};
        }
        match (self.x_log, self.y_log) {
            (true, true) => draw!((x0..x1).log_scale(), (y0..y1).log_scale()),
            (true, false) => draw!((x0..x1).log_scale(), y0..y1),
            (false, true) => draw!(x0..x1, (y0..y1).log_scale()),
            (false, false) => draw!(x0..x1, y0..y1),
        }
        root.present().map_err(|e| fail(&e))?;
        drop(root);
        Ok(svg)
    }
}

/// Writes `bytes` to `path` through a temporary file beside it, so a reader never sees half a
/// file and a failed run leaves the previous one in place.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut temporary = path.as_os_str().to_owned();
    temporary.push(".partial");
    let temporary = std::path::PathBuf::from(temporary);
    std::fs::write(&temporary, bytes).map_err(|e| Error::io(&temporary, "cannot write", e))?;
    std::fs::rename(&temporary, path).map_err(|e| {
        let _ = std::fs::remove_file(&temporary);
        Error::io(path, "cannot write", e)
    })
}
