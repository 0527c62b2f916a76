//! Figures of an [`Analysis`]: the performance profiles (fraction of runs above τ, with the
//! intervals as bands) and the aggregate intervals (one panel per aggregate, one bar per
//! algorithm from the lower to the upper end of its interval, a tick at the point estimate).
//! PNG or SVG by the file extension.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::plot::{color, font, render_image as render, GREY};
use crate::stats::{Aggregate, Analysis};

/// The performance profiles of `analysis` into `out` (placed as `place` says); `title` names the metric and `x_label`
/// the scores.
pub fn profiles(
    analysis: &Analysis,
    title: &str,
    x_label: &str,
    out: &Path,
    place: apo_train::atomic::Place,
) -> anyhow::Result<()> {
    fn draw<DB: DrawingBackend>(
        root: DrawingArea<DB, Shift>,
        analysis: &Analysis,
        title: &str,
        x_label: &str,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let taus = &analysis.profiles.taus;
        let (low, high) = match (taus.first(), taus.last()) {
            (Some(&l), Some(&h)) if h > l => (l, h),
            (Some(&l), _) => (l - 0.5, l + 0.5),
            _ => (0.0, 1.0),
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, font(22))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(low..high, 0.0..1.02)?;
        chart
            .configure_mesh()
            .label_style(font(15))
            .axis_desc_style(font(17))
            .x_desc(x_label)
            .y_desc("fraction of runs with score > τ")
            .max_light_lines(0)
            .bold_line_style(BLACK.mix(0.1))
            .draw()?;
        for (i, label) in analysis.algorithms.iter().enumerate() {
            let Some(p) = analysis.profiles.curves.get(label) else {
                continue;
            };
            let band: Vec<(f64, f64)> = taus
                .iter()
                .copied()
                .zip(p.upper.iter().copied())
                .chain(taus.iter().copied().zip(p.lower.iter().copied()).rev())
                .collect();
            chart.draw_series(std::iter::once(Polygon::new(
                band,
                color(i).mix(0.15).filled(),
            )))?;
            chart
                .draw_series(LineSeries::new(
                    taus.iter().copied().zip(p.fraction.iter().copied()),
                    color(i).stroke_width(2),
                ))?
                .label(label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], color(i).stroke_width(3))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(font(15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.3))
            .draw()?;
        root.present()?;
        Ok(())
    }
    render(
        out,
        (900, 600),
        &|a| draw(a, analysis, title, x_label),
        &|a| draw(a, analysis, title, x_label),
        place,
    )
}

/// The aggregate intervals of `analysis` into `out` (placed as `place` says): one panel per
/// [`Aggregate`].
pub fn intervals(
    analysis: &Analysis,
    title: &str,
    out: &Path,
    place: apo_train::atomic::Place,
) -> anyhow::Result<()> {
    fn draw<DB: DrawingBackend>(
        root: DrawingArea<DB, Shift>,
        analysis: &Analysis,
        title: &str,
    ) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (width, _) = root.dim_in_pixel();
        let (header, body) = root.split_vertically(50);
        header.draw(&Text::new(
            title,
            (width as i32 / 2, 12),
            font(22).pos(Pos::new(HPos::Center, VPos::Top)),
        ))?;
        let labels = &analysis.algorithms;
        let widest = labels
            .iter()
            .map(|l| body.estimate_text_size(l, &font(15)).map(|(w, _)| w))
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .max()
            .unwrap_or(0);
        let (names, panels) = body.split_horizontally(widest + 24);
        let n = labels.len().max(1) as f64;
        let panels = panels.split_evenly((1, Aggregate::ALL.len()));
        for (panel, aggregate) in panels.iter().zip(Aggregate::ALL) {
            let estimates: Vec<_> = labels
                .iter()
                .filter_map(|l| analysis.aggregates.get(l)?.get(aggregate.name()))
                .collect();
            let (mut low, mut high) = estimates
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| {
                    (lo.min(e.lower), hi.max(e.upper))
                });
            if !(low.is_finite() && high.is_finite()) {
                (low, high) = (0.0, 1.0);
            }
            let pad = ((high - low) * 0.08).max(1e-6);
            let caption = match aggregate {
                Aggregate::Mean => "mean",
                Aggregate::Median => "median",
                Aggregate::Iqm => "IQM",
                Aggregate::OptimalityGap => "optimality gap",
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(caption, font(18))
                .margin(10)
                .x_label_area_size(40)
                .build_cartesian_2d(low - pad..high + pad, -0.5..n - 0.5)?;
            chart
                .configure_mesh()
                .disable_y_mesh()
                .y_labels(0)
                .x_labels(4)
                .label_style(font(13))
                .max_light_lines(0)
                .bold_line_style(BLACK.mix(0.1))
                .draw()?;
            for (i, e) in estimates.iter().enumerate() {
                let y = n - 1.0 - i as f64;
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(e.lower, y - 0.3), (e.upper, y + 0.3)],
                    color(i).mix(0.6).filled(),
                )))?;
                chart.draw_series(std::iter::once(PathElement::new(
                    vec![(e.point, y - 0.38), (e.point, y + 0.38)],
                    BLACK.stroke_width(2),
                )))?;
            }
        }
        // the algorithms' names, level with their bars
        let (_, height) = names.dim_in_pixel();
        let top = 10 + 18 + 10; // the panels' margin and caption
        let plot_height = height as f64 - top as f64 - 40.0 - 10.0;
        for (i, label) in labels.iter().enumerate() {
            let y = top as f64 + plot_height * (i as f64 + 0.5) / n;
            names.draw(&Text::new(
                label.as_str(),
                (widest as i32 + 12, y as i32),
                font(15)
                    .color(&GREY)
                    .pos(Pos::new(HPos::Right, VPos::Center)),
            ))?;
        }
        root.present()?;
        Ok(())
    }
    let height = 150 + 50 * analysis.algorithms.len() as u32;
    render(
        out,
        (1200, height.min(2000)),
        &|a| draw(a, analysis, title),
        &|a| draw(a, analysis, title),
        place,
    )
}
