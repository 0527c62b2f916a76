//! Learning curves of one or more runs: mean return with its min–max band, and the
//! worst (minimum) return, against environment steps. PNG or SVG by the file extension.
//!
//! The title names the runs' environments and algorithms (from each run's `config.toml`);
//! the legend has its own panel beside the chart, so it never covers a curve. Returns that
//! are not finite (`inf`, `NaN`) are left out and counted (a note on stderr and in the
//! subtitle); returns spanning a range wider than an `f64` can hold are an error naming the
//! runs that hold the extremes.

use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use apo_train::progress_csv::{self, ProgressRow};

/// Options of [`plot`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlotOptions {
    /// Moving-average window over epochs (`--smooth N`), applied alike to the mean, worst and
    /// best returns: each point is the mean of its epoch and the `smooth − 1` epochs before it
    /// (of those that exist, for the first epochs). 1 draws the values as logged; 0 is an error.
    pub smooth: usize,
    /// Plot this numeric column of `progress.csv` (e.g. `kl`, `ls_rejected_objective`,
    /// `bias`; `true`/`false` as 1/0) instead of the returns (`None`).
    pub column: Option<String>,
    /// How the figure takes its place at `out` (`apo_train::atomic::Place`): `New` (the
    /// default) replaces nothing, a file that appeared while the figure was drawn included;
    /// `ReplacePlainFile` (`--force`) a plain file.
    pub place: apo_train::atomic::Place,
}

impl Default for PlotOptions {
    /// No smoothing; an existing file is not replaced.
    fn default() -> Self {
        Self {
            smooth: 1,
            column: None,
            place: apo_train::atomic::Place::New,
        }
    }
}

/// Image size in pixels.
const SIZE: (u32, u32) = (1200, 660);
/// Height of the title and subtitle band.
const HEADER_HEIGHT: u32 = 84;
/// Most labelled ticks per axis (the label formats rely on it, see [`ReturnTicks`]).
const X_LABELS: usize = 10;
/// See [`X_LABELS`].
const Y_LABELS: usize = 10;
/// Font size of tick labels and legend entries.
const LABEL_FONT: u32 = 16;
/// Height of a legend row.
const LEGEND_ROW: i32 = 24;
/// Length of a legend entry's line sample.
const SWATCH: i32 = 30;
/// Width bounds of the legend panel.
const LEGEND_WIDTH: Range<u32> = 190..360;
/// The runs' colors, in order (Tableau 10: distinct, and all readable on white).
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
/// Color of secondary text and of the legend's line-style samples.
pub(crate) const GREY: RGBColor = RGBColor(80, 80, 80);

/// The image formats by file extension.
enum ImageFormat {
    Png,
    Svg,
}

impl ImageFormat {
    fn of(out: &Path) -> anyhow::Result<Self> {
        match out
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(Self::Png),
            Some("svg") => Ok(Self::Svg),
            _ => bail!(
                "cannot tell the image format of {}: use a .png or .svg file name",
                out.display()
            ),
        }
    }
}

/// Points `(environment steps, return)`.
type Series = Vec<(f64, f64)>;

/// One run, ready to draw: finite returns only, smoothed.
struct Run {
    /// The run directory.
    dir: PathBuf,
    /// Its name in the legend (the directory's name).
    label: String,
    /// Its environment.
    env: String,
    /// Its algorithm.
    algo: &'static str,
    /// Mean return per epoch.
    mean: Series,
    /// Worst return per epoch (dashed).
    min: Series,
    /// The band's lower and upper edges per epoch.
    band: (Series, Series),
    /// Returns left out because they were not finite.
    skipped: usize,
    /// Environment steps after its last epoch.
    steps: f64,
}

impl Run {
    /// Reads the run in `dir` (`config.toml`, `progress.csv`) and smooths its curves.
    fn load(dir: &Path, smooth: usize, column_name: Option<&str>) -> anyhow::Result<Self> {
        let context = || format!("cannot plot the run in {}", dir.display());
        let config = apo_train::run_dir::load_config(dir)?;
        let rows = apo_train::run_dir::progress_of(dir)
            .and_then(|path| progress_csv::read_rows_with_non_finite(&path))
            .with_context(context)?;
        if let Some(name) = column_name {
            let (values, skipped) = named_column(&rows, name, smooth)
                .with_context(|| format!("run {}", dir.display()))?;
            return Ok(Self {
                dir: dir.to_path_buf(),
                label: dir_label(dir),
                env: config.train.env,
                algo: config.train.algo.algorithm().name(),
                mean: values,
                band: (vec![], vec![]),
                min: vec![],
                skipped,
                steps: rows.iter().map(|r| r.env_steps as f64).fold(0.0, f64::max),
            });
        }
        let (mean, skipped_mean) = column(&rows, |r| r.ep_ret_mean, smooth);
        let (min, skipped_min) = column(&rows, |r| r.ep_ret_min, smooth);
        let (max, skipped_max) = column(&rows, |r| r.ep_ret_max, smooth);
        Ok(Self {
            dir: dir.to_path_buf(),
            label: dir_label(dir),
            env: config.train.env,
            algo: config.train.algo.algorithm().name(),
            mean,
            band: (min.clone(), max),
            min,
            skipped: skipped_mean + skipped_min + skipped_max,
            steps: rows.iter().map(|r| r.env_steps as f64).fold(0.0, f64::max),
        })
    }

    /// Every drawn return.
    fn returns(&self) -> impl Iterator<Item = f64> + '_ {
        self.mean
            .iter()
            .chain(&self.min)
            .chain(&self.band.0)
            .chain(&self.band.1)
            .map(|&(_, y)| y)
    }

    /// The runs in `dirs` (seeds of one setting) as one curve set labelled `label`: per
    /// epoch, the mean over seeds of the mean return with a band of ± their standard
    /// deviation, and the mean over seeds of the worst return. An epoch counts the seeds
    /// that have it and an episode in it; steps are their mean.
    fn seeds(label: &str, dirs: &[PathBuf], smooth: usize) -> anyhow::Result<Self> {
        let first = dirs.first().context("a group without runs")?;
        let config = apo_train::run_dir::load_config(first)?;
        let runs = dirs
            .iter()
            .map(|dir| {
                apo_train::run_dir::progress_of(dir)
                    .and_then(|path| progress_csv::read_rows_with_non_finite(&path))
                    .with_context(|| format!("cannot plot the run in {}", dir.display()))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let epochs = runs.iter().map(Vec::len).max().unwrap_or(0);
        let (mut mean, mut lo, mut hi, mut min) = (vec![], vec![], vec![], vec![]);
        let mut skipped = 0;
        for e in 0..epochs {
            let rows: Vec<&ProgressRow> = runs.iter().filter_map(|r| r.get(e)).collect();
            let finite = |v: fn(&ProgressRow) -> Option<f64>| -> Vec<f64> {
                rows.iter().filter_map(|r| v(r)).collect()
            };
            let (means, worst) = (finite(|r| r.ep_ret_mean), finite(|r| r.ep_ret_min));
            let (means, bad_means): (Vec<f64>, Vec<f64>) =
                means.into_iter().partition(|v| v.is_finite());
            let (worst, bad_worst): (Vec<f64>, Vec<f64>) =
                worst.into_iter().partition(|v| v.is_finite());
            skipped += bad_means.len() + bad_worst.len();
            let x = rows.iter().map(|r| r.env_steps as f64).sum::<f64>() / rows.len() as f64;
            if !means.is_empty() {
                let (m, sd) = crate::summary::mean_std(&means);
                mean.push((x, m));
                lo.push((x, m - sd));
                hi.push((x, m + sd));
            }
            if !worst.is_empty() {
                min.push((x, crate::summary::mean_std(&worst).0));
            }
        }
        Ok(Self {
            dir: first.clone(),
            label: format!("{label} ({} seeds)", dirs.len()),
            env: config.train.env,
            algo: config.train.algo.algorithm().name(),
            steps: mean.last().map_or(0.0, |&(x, _)| x),
            mean: smoothed(mean, smooth),
            band: (smoothed(lo, smooth), smoothed(hi, smooth)),
            min: smoothed(min, smooth),
            skipped,
        })
    }
}

/// The finite values of one column against environment steps, smoothed over `smooth` epochs,
/// and how many values were left out for not being finite.
fn column(
    rows: &[ProgressRow],
    value: fn(&ProgressRow) -> Option<f64>,
    smooth: usize,
) -> (Series, usize) {
    let logged: Series = rows
        .iter()
        .filter_map(|r| value(r).map(|v| (r.env_steps as f64, v)))
        .collect();
    finite_smoothed(logged, smooth)
}

/// The finite points of `logged`, smoothed over `smooth` epochs, and how many were not finite.
fn finite_smoothed(logged: Series, smooth: usize) -> (Series, usize) {
    let (finite, skipped): (Series, Series) = logged.into_iter().partition(|&(_, y)| y.is_finite());
    (smoothed(finite, smooth), skipped.len())
}

/// `series` with its values smoothed by [`moving_average`] over `smooth` epochs.
fn smoothed(series: Series, smooth: usize) -> Series {
    let ys: Vec<f64> = series.iter().map(|&(_, y)| y).collect();
    series
        .iter()
        .map(|&(x, _)| x)
        .zip(moving_average(&ys, smooth))
        .collect()
}

/// A run's name in the legend: its directory's name.
fn dir_label(dir: &Path) -> String {
    dir.file_name().map_or_else(
        || dir.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// The finite values of the column `name` (numbers, or booleans as 1/0; empty cells are
/// left out) against environment steps, smoothed, and how many were not finite.
fn named_column(
    rows: &[ProgressRow],
    name: &str,
    smooth: usize,
) -> anyhow::Result<(Series, usize)> {
    let mut logged = Series::new();
    for row in rows {
        let value = serde_json::to_value(row)?;
        let Some(cell) = value.get(name) else {
            let serde_json::Value::Object(fields) = &value else {
                bail!("progress rows are not records");
            };
            let names: Vec<&str> = fields.keys().map(String::as_str).collect();
            bail!(
                "progress.csv has no column `{name}` (columns: {})",
                names.join(", ")
            );
        };
        let y = match cell {
            serde_json::Value::Number(n) => n.as_f64(),
            serde_json::Value::Bool(b) => Some(f64::from(u8::from(*b))),
            serde_json::Value::Null => None,
            _ => bail!("progress.csv's column `{name}` is not numeric"),
        };
        logged.extend(y.map(|y| (row.env_steps as f64, y)));
    }
    Ok(finite_smoothed(logged, smooth))
}

/// Trailing moving average: element `i` is the mean of `values[i + 1 − window ..= i]`, or of
/// `values[..= i]` for the first `window − 1` elements; a window of 1 (or 0) changes nothing.
/// Each term is divided before summing, so finite values never overflow to infinity.
fn moving_average(values: &[f64], window: usize) -> Vec<f64> {
    let window = window.max(1);
    // each window's sum from a tree of pairwise sums (O(n log n) whatever the window), of the
    // values scaled by a power of two at least the window (exactly, so no sum overflows)
    let scale = (window as f64).log2().ceil().exp2();
    let tree = crate::stats::RangeSum::new(values.iter().map(|v| v / scale));
    (0..values.len())
        .map(|i| {
            let from = (i + 1).saturating_sub(window);
            tree.sum(from, i + 1) / (i + 1 - from) as f64 * scale
        })
        .collect()
}

/// The distinct items, in order of first appearance.
fn distinct<'a>(items: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut seen = Vec::new();
    for item in items {
        if !seen.contains(&item) {
            seen.push(item);
        }
    }
    seen
}

/// The return axis: the returns' range with a 5 % margin. Flat curves (a spread under a
/// millionth of their size, e.g. CartPole solved at 500) get ±5 % of their value, at least ±1,
/// so that the ticks stay readable.
///
/// The values of `column` when one is plotted, else the returns. An axis wider than the
/// largest `f64` is an error naming the runs with the extremes
/// (plotters' tick placement loops forever on an infinite range).
fn return_axis(runs: &[Run], column: Option<&str>) -> anyhow::Result<Range<f64>> {
    let extreme = |better: fn(f64, f64) -> bool| {
        runs.iter()
            .flat_map(|run| run.returns().map(move |y| (y, run)))
            .reduce(|a, b| if better(b.0, a.0) { b } else { a })
    };
    let (Some((lo, lo_run)), Some((hi, hi_run))) = (extreme(|a, b| a < b), extreme(|a, b| a > b))
    else {
        match column {
            Some(name) => bail!(
                "progress.csv's column `{name}` has no finite number to plot in these runs: it is empty in \
                 every epoch (e.g. `line_search` of an algorithm without a line search, `success_rate` of a \
                 task that judges no success)"
            ),
            None => bail!("the runs have no completed episode with a finite return to plot yet"),
        }
    };
    let span = hi - lo;
    let (start, end) = if span <= 1e-6 * lo.abs().max(hi.abs()).max(1.0) {
        let mid = lo / 2.0 + hi / 2.0;
        let half = (mid.abs() * 0.05).max(1.0);
        (mid - half, mid + half)
    } else {
        (lo - span * 0.05, hi + span * 0.05)
    };
    if !(end - start).is_finite() {
        bail!(
            "cannot plot returns from {lo:e} (in {}) to {hi:e} (in {}): the range is too wide for a \
             floating-point axis (has a run diverged?)",
            lo_run.dir.display(),
            hi_run.dir.display()
        );
    }
    Ok(start..end)
}

/// Environment steps as tick labels: 0, 500, 50k, 1.2M, 3G.
fn format_steps(steps: f64) -> String {
    let (scaled, suffix) = match steps.abs() {
        a if a >= 1e9 => (steps / 1e9, "G"),
        a if a >= 1e6 => (steps / 1e6, "M"),
        a if a >= 1e3 => (steps / 1e3, "k"),
        _ => (steps, ""),
    };
    let digits = format!("{scaled:.2}");
    let digits = digits.trim_end_matches('0').trim_end_matches('.');
    format!("{}{suffix}", if digits == "-0" { "0" } else { digits })
}

/// Tick labels of the return axis: the fewest decimals that show plotters' ticks exactly
/// (no `0.30000000000000004`), in scientific notation from a million on.
struct ReturnTicks {
    /// Decimals (of the mantissa, in scientific notation).
    decimals: usize,
    /// Whether to use scientific notation.
    scientific: bool,
}

impl ReturnTicks {
    fn new(axis: &Range<f64>) -> Self {
        let ticks = RangedCoordf64::from(axis.clone()).key_points(Y_LABELS);
        let spacing = ticks
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(axis.end - axis.start, f64::min);
        let scientific = axis.start.abs().max(axis.end.abs()) >= 1e6;
        let exact = |decimals: usize| {
            ticks.iter().all(|&t| {
                Self {
                    decimals,
                    scientific,
                }
                .format(t)
                .parse::<f64>()
                .is_ok_and(|shown| (shown - t).abs() <= spacing * 1e-3)
            })
        };
        Self {
            decimals: (0..=15).find(|&d| exact(d)).unwrap_or(15),
            scientific,
        }
    }

    fn format(&self, value: f64) -> String {
        let text = if self.scientific {
            // each mantissa as short as it can be: 5e6, 1e7, 1.5e7
            let text = format!("{value:.*e}", self.decimals);
            match text.split_once('e') {
                Some((mantissa, exponent)) if mantissa.contains('.') => {
                    format!(
                        "{}e{exponent}",
                        mantissa.trim_end_matches('0').trim_end_matches('.')
                    )
                }
                _ => text,
            }
        } else {
            format!("{value:.*}", self.decimals)
        };
        match text.parse::<f64>() {
            // 0, not "0e0", "-0" or "-0.00"
            Ok(0.0) if self.scientific => "0".to_string(),
            Ok(0.0) => text.trim_start_matches('-').to_string(),
            _ => text,
        }
    }
}

/// What the image shows.
struct Figure<'a> {
    runs: &'a [Run],
    key: &'static [(&'static str, Sample)],
    y_label: String,
    title: String,
    subtitle: String,
    x: Range<f64>,
    y: Range<f64>,
}

impl<'a> Figure<'a> {
    fn new(runs: &'a [Run], options: &PlotOptions, seeds: bool) -> anyhow::Result<Self> {
        let envs = distinct(runs.iter().map(|r| r.env.as_str()));
        let algos = distinct(runs.iter().map(|r| r.algo));
        let (mut subtitle, key): (String, &'static [(&str, Sample)]) = match &options.column {
            Some(name) => (format!("progress.csv column `{name}`"), &[]),
            None if seeds => (
                "Episode return, over seeds: mean of the mean (solid) ± std band, mean of the worst (dashed)"
                    .to_string(),
                &SEEDS_KEY,
            ),
            None => (
                "Episode return: mean (solid), min–max band, worst (dashed)".to_string(),
                &LEGEND_KEY,
            ),
        };
        if options.smooth > 1 {
            subtitle += &format!(" · moving average over {} epochs", options.smooth);
        }
        let skipped: usize = runs.iter().map(|r| r.skipped).sum();
        if skipped > 0 {
            subtitle += &format!(
                " · {skipped} non-finite value{} left out",
                if skipped == 1 { "" } else { "s" }
            );
        }
        Ok(Self {
            runs,
            key,
            y_label: options
                .column
                .clone()
                .unwrap_or_else(|| "episode return".to_string()),
            title: format!("{} — {}", envs.join(", "), algos.join(", ")),
            subtitle,
            x: 0.0..runs.iter().map(|r| r.steps).fold(1.0, f64::max),
            y: return_axis(runs, options.column.as_deref())?,
        })
    }

    /// Draws the figure: title band on top, chart on the left, legend panel on the right.
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (width, _) = root.dim_in_pixel();
        let (header, body) = root.split_vertically(HEADER_HEIGHT);
        let centered = Pos::new(HPos::Center, VPos::Top);
        header.draw(&Text::new(
            self.title.as_str(),
            (width as i32 / 2, 14),
            font(28).pos(centered),
        ))?;
        header.draw(&Text::new(
            self.subtitle.as_str(),
            (width as i32 / 2, 54),
            font(17).color(&GREY).pos(centered),
        ))?;

        let labels: Vec<&str> = self.runs.iter().map(|r| r.label.as_str()).collect();
        let widest = labels
            .iter()
            .chain(self.key.iter().map(|(text, _)| text))
            .map(|text| {
                body.estimate_text_size(text, &font(LABEL_FONT))
                    .map(|(w, _)| w)
            })
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .max()
            .unwrap_or(0);
        let legend_width =
            (widest + LEGEND_TEXT_X as u32 + 16).clamp(LEGEND_WIDTH.start, LEGEND_WIDTH.end);
        let (chart_area, legend_area) = body.split_horizontally(width - legend_width);
        self.draw_chart(&chart_area)?;
        draw_legend(&legend_area, &labels, self.key)?;
        root.present()?;
        Ok(())
    }

    fn draw_chart<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<()>
    where
        DB::ErrorType: 'static,
    {
        let ticks = ReturnTicks::new(&self.y);
        let tick_width = [self.y.start, self.y.end]
            .into_iter()
            .map(|y| {
                area.estimate_text_size(&ticks.format(y), &font(LABEL_FONT))
                    .map(|(w, _)| w)
            })
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .max()
            .unwrap_or(0);
        let mut chart = ChartBuilder::on(area)
            .margin_left(12)
            .margin_right(28)
            .margin_top(10)
            .margin_bottom(12)
            .x_label_area_size(56)
            .y_label_area_size(tick_width + 48)
            .build_cartesian_2d(self.x.clone(), self.y.clone())?;
        chart
            .configure_mesh()
            .x_labels(X_LABELS)
            .y_labels(Y_LABELS)
            .x_label_formatter(&|x| format_steps(*x))
            .y_label_formatter(&|y| ticks.format(*y))
            .label_style(font(LABEL_FONT))
            .axis_desc_style(font(18))
            .x_desc("environment steps")
            .y_desc(self.y_label.as_str())
            .max_light_lines(0)
            .bold_line_style(BLACK.mix(0.1))
            .draw()?;
        // bands first, so that no run's band covers another run's lines; fainter the more
        // runs overlap
        let opacity = (0.3 / self.runs.len() as f64).clamp(0.04, 0.15);
        for (i, run) in self.runs.iter().enumerate() {
            let band: Series = run
                .band
                .1
                .iter()
                .chain(run.band.0.iter().rev())
                .copied()
                .collect();
            if band.len() > 2 {
                chart.draw_series(std::iter::once(Polygon::new(
                    band,
                    color(i).mix(opacity).filled(),
                )))?;
            }
        }
        for (i, run) in self.runs.iter().enumerate() {
            let color = color(i);
            chart.draw_series(LineSeries::new(
                run.mean.iter().copied(),
                color.stroke_width(2),
            ))?;
            chart.draw_series(DashedLineSeries::new(
                run.min.iter().copied(),
                8,
                5,
                color.stroke_width(2),
            ))?;
            if run.mean.len() == 1 {
                // a single epoch makes no line: mark it
                chart.draw_series(run.mean.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
            }
        }
        Ok(())
    }
}

/// The legend's line-style key: text and sample.
const LEGEND_KEY: [(&str, Sample); 3] = [
    ("mean return", Sample::Solid),
    ("min–max band", Sample::Band),
    ("worst return", Sample::Dashed),
];
/// The key of curves over seeds.
const SEEDS_KEY: [(&str, Sample); 3] = [
    ("mean return", Sample::Solid),
    ("± std over seeds", Sample::Band),
    ("worst return", Sample::Dashed),
];
/// Where the legend's texts start.
const LEGEND_TEXT_X: i32 = 12 + SWATCH + 10;

/// A legend entry's sample.
#[derive(Clone, Copy)]
enum Sample {
    Solid,
    Band,
    Dashed,
}

/// The legend panel: one entry per run (as many as fit), then the line-style key.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    labels: &[&str],
    key: &[(&str, Sample)],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let (width, height) = area.dim_in_pixel();
    let text_width = width.saturating_sub(LEGEND_TEXT_X as u32 + 8);
    let text = font(LABEL_FONT).pos(Pos::new(HPos::Left, VPos::Center));
    let heading = font(LABEL_FONT + 1)
        .color(&GREY)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let entry = |y: i32, label: &str, sample: Sample, color: RGBColor| -> anyhow::Result<()> {
        let line = [(12, y), (12 + SWATCH, y)];
        match sample {
            Sample::Solid => area.draw(&PathElement::new(line, color.stroke_width(3)))?,
            Sample::Band => area.draw(&Rectangle::new(
                [(12, y - 7), (12 + SWATCH, y + 7)],
                color.mix(0.2).filled(),
            ))?,
            Sample::Dashed => {
                area.draw(&DashedPathElement::new(line, 8, 5, color.stroke_width(2)))?
            }
        }
        area.draw(&Text::new(
            fit(area, label, text_width)?,
            (LEGEND_TEXT_X, y),
            text.clone(),
        ))?;
        Ok(())
    };

    // rows for the two headings, the key, a gap and a possible "… more" line
    let room = (height as i32 / LEGEND_ROW - 2 - key.len() as i32 - 2).max(1) as usize;
    let shown = if labels.len() > room {
        room - 1
    } else {
        labels.len()
    };
    let mut y = 22;
    area.draw(&Text::new("Runs", (12, y), heading.clone()))?;
    for (i, label) in labels.iter().take(shown).enumerate() {
        y += LEGEND_ROW;
        entry(y, label, Sample::Solid, color(i))?;
    }
    if shown < labels.len() {
        y += LEGEND_ROW;
        area.draw(&Text::new(
            format!("… and {} more", labels.len() - shown),
            (LEGEND_TEXT_X, y),
            text.clone(),
        ))?;
    }
    if key.is_empty() {
        return Ok(());
    }
    y += 2 * LEGEND_ROW;
    area.draw(&Text::new("Lines", (12, y), heading))?;
    for &(label, sample) in key {
        y += LEGEND_ROW;
        entry(y, label, sample, GREY)?;
    }
    Ok(())
}

/// `text`, shortened with an ellipsis to fit `width` pixels in the legend's font.
fn fit<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    width: u32,
) -> anyhow::Result<String>
where
    DB::ErrorType: 'static,
{
    let mut chars: Vec<char> = text.chars().collect();
    let mut candidate = text.to_string();
    while !chars.is_empty() && area.estimate_text_size(&candidate, &font(LABEL_FONT))?.0 > width {
        chars.pop();
        candidate = chars.iter().collect::<String>() + "…";
    }
    Ok(candidate)
}

/// The plot's font at `size` pixels.
pub(crate) fn font(size: u32) -> TextStyle<'static> {
    TextStyle::from(("sans-serif", size).into_font())
}

/// The color of the `i`-th run.
pub(crate) fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Plots the runs in `runs` into `out` (`.png` or `.svg`).
pub fn plot(runs: &[PathBuf], out: &Path, options: &PlotOptions) -> anyhow::Result<()> {
    if options.smooth == 0 {
        bail!("--smooth must be at least 1 (1 = no smoothing), got 0");
    }
    if runs.is_empty() {
        bail!("no run directory given");
    }
    ImageFormat::of(out)?;
    let runs = runs
        .iter()
        .map(|dir| Run::load(dir, options.smooth, options.column.as_deref()))
        .collect::<anyhow::Result<Vec<_>>>()?;
    for run in runs.iter().filter(|r| r.skipped > 0) {
        apo_train::warnln!(
            "note: {}: left out {} non-finite return value{} (inf or NaN)",
            run.dir.display(),
            run.skipped,
            if run.skipped == 1 { "" } else { "s" }
        );
    }
    draw(&Figure::new(&runs, options, false)?, out, options.place)
}

fn draw(figure: &Figure<'_>, out: &Path, place: apo_train::atomic::Place) -> anyhow::Result<()> {
    render_image(out, SIZE, &|a| figure.draw(a), &|a| figure.draw(a), place)
}

/// Draws a figure of `size` pixels into `out`, PNG or SVG by its extension: in memory, then
/// written atomically (a failed or interrupted draw leaves `out` as it was) and placed as
/// `place` says. `svg` and `bitmap` draw the same figure on either backend.
///
/// # Errors
/// Another extension, a drawing error, a failed write (naming `out`).
pub(crate) fn render_image(
    out: &Path,
    size: (u32, u32),
    svg: &dyn Fn(DrawingArea<SVGBackend<'_>, Shift>) -> anyhow::Result<()>,
    bitmap: &dyn Fn(DrawingArea<BitMapBackend<'_>, Shift>) -> anyhow::Result<()>,
    place: apo_train::atomic::Place,
) -> anyhow::Result<()> {
    apo_train::video::load_font()?;
    let bytes = match ImageFormat::of(out)? {
        ImageFormat::Svg => {
            let mut text = String::new();
            svg(SVGBackend::with_string(&mut text, size).into_drawing_area())
                .with_context(|| format!("cannot draw {}", out.display()))?;
            text.into_bytes()
        }
        ImageFormat::Png => {
            let (w, h) = (size.0 as usize, size.1 as usize);
            let mut rgb = vec![0u8; w * h * 3];
            bitmap(BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area())
                .with_context(|| format!("cannot draw {}", out.display()))?;
            let mut png_bytes = Vec::new();
            let mut encoder = png::Encoder::new(&mut png_bytes, size.0, size.1);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            encoder
                .write_header()
                .and_then(|mut w| w.write_image_data(&rgb))
                .with_context(|| format!("cannot encode {}", out.display()))?;
            png_bytes
        }
    };
    apo_train::atomic::write_placed(out, &bytes, place)
        .with_context(|| format!("cannot write {}", out.display()))
}

/// Plots groups of runs into `out` (`.png` or `.svg`), one curve set per group `(label,
/// run directories)`: the mean over the group's seeds of the mean return, a band of ± the
/// standard deviation over seeds, and the mean over seeds of the worst return.
pub fn plot_seed_groups(
    groups: &[(String, Vec<PathBuf>)],
    out: &Path,
    options: &PlotOptions,
) -> anyhow::Result<()> {
    if options.smooth == 0 {
        bail!("--smooth must be at least 1 (1 = no smoothing), got 0");
    }
    ImageFormat::of(out)?;
    let runs = groups
        .iter()
        .map(|(label, dirs)| Run::seeds(label, dirs, options.smooth))
        .collect::<anyhow::Result<Vec<_>>>()?;
    draw(&Figure::new(&runs, options, true)?, out, options.place)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moving_average_is_trailing_and_averages_what_exists_at_the_start() {
        let smoothed = moving_average(&[1.0, 2.0, 3.0, 4.0, 5.0], 3);
        for (got, want) in smoothed.iter().zip([1.0, 1.5, 2.0, 3.0, 4.0]) {
            assert!((got - want).abs() < 1e-12, "{smoothed:?}");
        }
        assert_eq!(moving_average(&[1.0, 7.0], 1), [1.0, 7.0]);
        assert_eq!(moving_average(&[2.0, 4.0], 10), [2.0, 3.0]);
        assert!(moving_average(&[], 3).is_empty());
        // any window, against the direct mean of each window's values
        let values: Vec<f64> = (0..200).map(|i| ((i * 37) % 101) as f64 - 50.5).collect();
        for window in [1, 2, 7, 64, 100, 1000] {
            for (i, got) in moving_average(&values, window).iter().enumerate() {
                let terms = &values[(i + 1).saturating_sub(window)..=i];
                let want = terms.iter().sum::<f64>() / terms.len() as f64;
                assert!(
                    (got - want).abs() < 1e-12,
                    "window {window}, {i}: {got} vs {want}"
                );
            }
        }
        assert_eq!(
            moving_average(&[1e308, 1e308], 2),
            [1e308, 1e308],
            "no overflow"
        );
    }

    #[test]
    fn step_ticks_use_k_and_m_suffixes() {
        for (steps, label) in [
            (0.0, "0"),
            (500.0, "500"),
            (1500.0, "1.5k"),
            (50_000.0, "50k"),
            (1_200_000.000_000_2, "1.2M"),
            (1_250_000.0, "1.25M"),
            (3e9, "3G"),
        ] {
            assert_eq!(format_steps(steps), label);
        }
    }

    #[test]
    fn return_ticks_have_the_precision_of_their_spacing() {
        let labels = |axis: Range<f64>| {
            let ticks = ReturnTicks::new(&axis);
            RangedCoordf64::from(axis)
                .key_points(Y_LABELS)
                .into_iter()
                .map(|t| ticks.format(t))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            labels(-20.0..520.0),
            ["0", "100", "200", "300", "400", "500"]
        );
        assert_eq!(
            labels(0.0..1.2),
            ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0", "1.2"]
        );
        assert_eq!(labels(-0.25..0.25), ["-0.2", "-0.1", "0.0", "0.1", "0.2"]);
        assert_eq!(labels(0.0..0.4)[..3], ["0.00", "0.05", "0.10"]);
        assert_eq!(labels(0.0..3e7)[..4], ["0", "5e6", "1e7", "1.5e7"]);
        assert_eq!(
            ReturnTicks {
                decimals: 2,
                scientific: false
            }
            .format(-0.001),
            "0.00"
        );
    }
}
