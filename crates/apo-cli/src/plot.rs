//! Learning curves of one or more runs: mean return with its min–max band, and the
//! worst (minimum) return, against environment steps. PNG or SVG by the file extension.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use crate::progress::{self, ProgressRow};

/// Where the font for the plot's text is looked for (Debian's `fonts-dejavu-core`).
const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

fn load_font() -> anyhow::Result<()> {
    let path = FONT_PATHS.iter().map(PathBuf::from).find(|p| p.exists()).context(
        "no font for the plot's text: install Debian's fonts-dejavu-core (apt-get install fonts-dejavu-core)",
    )?;
    let bytes = std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    register_font("sans-serif", FontStyle::Normal, bytes).map_err(|_| anyhow::anyhow!("{} is not a usable font", path.display()))
}

/// One run's curve.
struct Curve {
    label: String,
    rows: Vec<ProgressRow>,
}

/// Plots the runs in `runs` into `out` (`.png` or `.svg`).
pub fn plot(runs: &[PathBuf], out: &Path) -> anyhow::Result<()> {
    if runs.is_empty() {
        bail!("no run directory given");
    }
    let curves = runs
        .iter()
        .map(|dir| {
            let rows = progress::read(&dir.join("progress.csv"))?;
            let label = dir.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned());
            Ok(Curve { label, rows })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    load_font()?;
    match out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("png") => draw(BitMapBackend::new(out, (1000, 640)).into_drawing_area(), &curves),
        Some("svg") => draw(SVGBackend::new(out, (1000, 640)).into_drawing_area(), &curves),
        _ => bail!("cannot tell the image format of {}: use a .png or .svg file name", out.display()),
    }
}

fn draw<DB: DrawingBackend>(area: DrawingArea<DB, plotters::coord::Shift>, curves: &[Curve]) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing failed: {e:?}");
    area.fill(&WHITE).map_err(err)?;
    let points = curves.iter().flat_map(|c| c.rows.iter());
    let x_max = points.clone().map(|r| r.env_steps as f64).fold(1.0, f64::max);
    let ys: Vec<f64> = points.flat_map(|r| [r.ep_ret_min, r.ep_ret_max, r.ep_ret_mean]).flatten().collect();
    if ys.is_empty() {
        bail!("the runs have no completed episode to plot yet");
    }
    let (y_min, y_max) = ys.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &y| (lo.min(y), hi.max(y)));
    let pad = ((y_max - y_min) * 0.05).max(1e-6);
    let mut chart = ChartBuilder::on(&area)
        .caption("Episode return: mean (solid), min–max band, worst (dashed)", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..x_max, (y_min - pad)..(y_max + pad))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("environment steps")
        .y_desc("return")
        .draw()
        .map_err(err)?;
    for (i, curve) in curves.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let rows: Vec<&ProgressRow> = curve.rows.iter().filter(|r| r.ep_ret_mean.is_some()).collect();
        let at = |r: &ProgressRow, v: Option<f64>| (r.env_steps as f64, v.unwrap_or(f64::NAN));
        let band: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| at(r, r.ep_ret_max))
            .chain(rows.iter().rev().map(|r| at(r, r.ep_ret_min)))
            .collect();
        chart.draw_series(std::iter::once(Polygon::new(band, color.mix(0.15).filled()))).map_err(err)?;
        chart
            .draw_series(LineSeries::new(rows.iter().map(|r| at(r, r.ep_ret_mean)), color.stroke_width(2)))
            .map_err(err)?
            .label(curve.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        chart
            .draw_series(DashedLineSeries::new(rows.iter().map(|r| at(r, r.ep_ret_min)), 6, 4, color.stroke_width(1)))
            .map_err(err)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(err)?;
    area.present().map_err(err)?;
    Ok(())
}
