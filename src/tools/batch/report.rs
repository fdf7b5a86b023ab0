//! The report of a plan, from whatever cells exist (000 ch. 4 and Appendix B): per scene and
//! camera, thumbnails of the reference and of each technique's best cell, a table per error
//! measure ([`Metric::ALL`]: mean absolute and RMS error as in Table B.1 and Table 4.2, relative
//! MSE, FLIP, SSIM) per radius and technique with the best radius marked, error-against-radius
//! charts (Fig. 4.1) and log-log convergence charts per
//! technique and trace window; the tables also as CSV, Markdown and LaTeX. A static page with
//! relative links only, so the folder can be copied anywhere and opened without a network.

use super::cell::{CellKind, State};
use super::{BatchError, Cell, Plan};
use crate::film::{atomic_write, exr, png, ErrorSample, Metadata};
use crate::tools::{draw_charts, Chart, ChartSeries, Metric};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// A rendered cell of the report.
struct Entry<'a> {
    cell: &'a Cell,
    metadata: &'a Metadata,
    last: &'a ErrorSample,
    partial: bool,
}

/// The errors of one scene and camera as a radius x technique table: rows by radius (`None`
/// for the techniques without one), columns by variant, each cell the mean over seeds.
struct Table {
    metric: Metric,
    variants: Vec<String>,
    radii: Vec<Option<f32>>,
    /// `values[row][column]`.
    values: Vec<Vec<Option<f64>>>,
}

impl Table {
    fn new(entries: &[Entry], metric: Metric) -> Table {
        let mut variants: Vec<String> = Vec::new();
        let mut radii: Vec<Option<f32>> = Vec::new();
        for e in entries {
            if !variants.contains(&e.cell.variant) {
                variants.push(e.cell.variant.clone());
            }
            if !radii.contains(&e.cell.options.radius) {
                radii.push(e.cell.options.radius);
            }
        }
        radii.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
        let values = radii
            .iter()
            .map(|r| {
                variants
                    .iter()
                    .map(|v| {
                        let here: Vec<f64> = entries
                            .iter()
                            .filter(|e| e.cell.variant == *v && e.cell.options.radius == *r)
                            .filter_map(|e| e.last.get(metric))
                            .collect();
                        (!here.is_empty()).then(|| here.iter().sum::<f64>() / here.len() as f64)
                    })
                    .collect()
            })
            .collect();
        Table {
            metric,
            variants,
            radii,
            values,
        }
    }

    /// Whether any cell holds the measure (the perceptual ones are missing from renders made
    /// before they were measured).
    fn is_empty(&self) -> bool {
        self.values.iter().flatten().all(Option::is_none)
    }

    /// The row of each column's best value: the lowest, the highest for SSIM.
    fn best(&self) -> Vec<Option<usize>> {
        (0..self.variants.len())
            .map(|c| {
                (0..self.radii.len())
                    .filter_map(|r| self.values[r][c].map(|v| (r, self.metric.as_error(v))))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(r, _)| r)
            })
            .collect()
    }
}

fn radius_text(r: Option<f32>) -> String {
    r.map_or("-".into(), |r| r.to_string())
}

/// Four significant digits, in decimals where they read well.
fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return x.to_string();
    }
    if (1e-3..1e4).contains(&x.abs()) {
        let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
        format!("{x:.digits$}")
    } else {
        format!("{x:.3e}")
    }
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn latex_escape(s: &str) -> String {
    s.replace('\\', "\\textbackslash{}")
        .replace('_', "\\_")
        .replace('&', "\\&")
        .replace('%', "\\%")
        .replace('#', "\\#")
}

/// The table as CSV (exact numbers; a last row `best` with each column's best radius),
/// Markdown and LaTeX (booktabs; the lowest of each column bold).
fn table_files(t: &Table) -> [String; 3] {
    let best = t.best();
    let mut csv = format!("radius,{}\n", t.variants.join(","));
    let mut md = format!(
        "| radius | {} |\n|---:|{}\n",
        t.variants.join(" | "),
        "---:|".repeat(t.variants.len())
    );
    let mut tex = format!(
        "\\begin{{tabular}}{{l{}}}\n\\toprule\nradius & {} \\\\\n\\midrule\n",
        "r".repeat(t.variants.len()),
        t.variants
            .iter()
            .map(|v| latex_escape(v))
            .collect::<Vec<_>>()
            .join(" & ")
    );
    for (r, row) in t.values.iter().enumerate() {
        let radius = radius_text(t.radii[r]);
        let exact: Vec<String> = row
            .iter()
            .map(|v| v.map_or(String::new(), |v| v.to_string()))
            .collect();
        let _ = writeln!(csv, "{radius},{}", exact.join(","));
        let shown = |bold: &dyn Fn(&str) -> String, empty: &str| -> Vec<String> {
            row.iter()
                .enumerate()
                .map(|(c, v)| match v {
                    Some(v) if best[c] == Some(r) => bold(&short(*v)),
                    Some(v) => short(*v),
                    None => empty.into(),
                })
                .collect()
        };
        let _ = writeln!(
            md,
            "| {radius} | {} |",
            shown(&|s| format!("**{s}**"), "").join(" | ")
        );
        let _ = writeln!(
            tex,
            "{radius} & {} \\\\",
            shown(&|s| format!("\\textbf{{{s}}}"), "--").join(" & ")
        );
    }
    let best_radii: Vec<String> = best
        .iter()
        .map(|b| b.map_or(String::new(), |r| radius_text(t.radii[r])))
        .collect();
    let _ = writeln!(csv, "best,{}", best_radii.join(","));
    tex.push_str("\\bottomrule\n\\end{tabular}\n");
    [csv, md, tex]
}

fn table_html(t: &Table, caption: &str) -> String {
    let best = t.best();
    let mut h = format!(
        "<table><caption>{}</caption><tr><th>radius</th>",
        html_escape(caption)
    );
    for v in &t.variants {
        let _ = write!(h, "<th>{}</th>", html_escape(v));
    }
    h.push_str("</tr>\n");
    for (r, row) in t.values.iter().enumerate() {
        let _ = write!(h, "<tr><th>{}</th>", radius_text(t.radii[r]));
        for (c, v) in row.iter().enumerate() {
            match v {
                Some(v) if best[c] == Some(r) => {
                    let _ = write!(h, "<td class=\"best\"><strong>{}</strong></td>", short(*v));
                }
                Some(v) => {
                    let _ = write!(h, "<td>{}</td>", short(*v));
                }
                None => h.push_str("<td></td>"),
            }
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    h
}

fn write_text(path: &Path, text: &str) -> Result<(), BatchError> {
    atomic_write(path, |f| f.write_all(text.as_bytes())).map_err(|e| BatchError::Write {
        file: path.into(),
        message: e.to_string(),
    })
}

fn make_dir(path: &Path) -> Result<(), BatchError> {
    std::fs::create_dir_all(path).map_err(|e| BatchError::Write {
        file: path.into(),
        message: e.to_string(),
    })
}

/// `target` relative to the report folder, which lies in the plan's output folder.
fn from_report(target: &Path, output: &Path) -> String {
    match target.strip_prefix(output) {
        Ok(rest) => format!("../{}", rest.to_string_lossy()),
        Err(_) => std::fs::canonicalize(target)
            .unwrap_or_else(|_| target.to_path_buf())
            .to_string_lossy()
            .into_owned(),
    }
}

const STYLE: &str = "body{font-family:sans-serif;margin:2em;color:#222}\
figure{display:inline-block;margin:0 1em 1em 0;vertical-align:top}\
figure img{width:192px;image-rendering:pixelated;border:1px solid #999}\
figcaption{font-size:0.85em;max-width:192px}\
table{border-collapse:collapse;margin:0.5em 0 1.5em}\
td,th{border:1px solid #bbb;padding:0.2em 0.6em;text-align:right}\
td.best{background:#dfd}caption{text-align:left;font-weight:bold;padding:0.3em 0}\
img.chart{max-width:100%;width:720px;display:block;margin-bottom:1em}";

/// Writes the report of `plan` into `OUTPUT/report/` and returns the path of its index.html.
pub fn report(plan: &Plan) -> Result<PathBuf, BatchError> {
    let dir = plan.output.join("report");
    for sub in ["", "images", "charts", "tables"] {
        make_dir(&dir.join(sub))?;
    }
    let states: Vec<State> = plan.cells.iter().map(|c| c.state(&plan.cells)).collect();
    let mut counts = std::collections::BTreeMap::new();
    for s in &states {
        *counts.entry(s.word()).or_insert(0) += 1;
    }
    let mut html = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>vmerge batch \
         report: {name}</title><style>{STYLE}</style></head><body>\n<h1>vmerge batch report: \
         {name}</h1>\n<p>{cells} cells: {summary}. Errors are the last measurement of each \
         cell against its reference; a technique's best cell is its lowest {metric}.</p>\n",
        name = html_escape(&plan.file.to_string_lossy()),
        cells = plan.cells.len(),
        summary = counts
            .iter()
            .map(|(k, v)| format!("{v} {k}"))
            .collect::<Vec<_>>()
            .join(", "),
        metric = plan.metric.label(),
    );
    for (scene, camera) in &plan.views {
        let view = format!("{scene}.{camera}");
        let _ = writeln!(
            html,
            "<section id=\"{id}\"><h2>{id}</h2>",
            id = html_escape(&view)
        );
        let entries: Vec<Entry> = plan
            .cells
            .iter()
            .zip(&states)
            .filter(|(c, _)| c.kind == CellKind::Render && c.scene == *scene && c.camera == *camera)
            .filter_map(|(cell, state)| {
                let metadata = state.metadata()?;
                Some(Entry {
                    cell,
                    metadata,
                    last: metadata.errors.last()?,
                    partial: matches!(state, State::Partial { .. }),
                })
            })
            .collect();
        html.push_str("<div class=\"thumbs\">\n");
        let reference = plan
            .cells
            .iter()
            .find(|c| c.kind == CellKind::Render && c.scene == *scene && c.camera == *camera)
            .and_then(|c| c.reference_file(&plan.cells));
        if let Some(reference) = reference.filter(|r| r.exists()) {
            let image = exr::read_image(reference)?;
            let name = format!("images/{view}.reference.png");
            png::write_preview(&dir.join(&name), &image.pixels, image.width, image.height)?;
            let about = match exr::read_render(reference) {
                Ok((_, m)) => format!(
                    "{}, {} spp, {:.1} s",
                    m.options.technique, m.iterations, m.render_seconds
                ),
                Err(_) => "a plain image".into(),
            };
            let _ = writeln!(
                html,
                "<figure><a href=\"{link}\"><img src=\"{name}\" alt=\"reference\"></a>\
                 <figcaption>reference<br>{about}</figcaption></figure>",
                link = html_escape(&from_report(reference, &plan.output)),
            );
        }
        let mut table = Table::new(&entries, plan.metric);
        let best = table.best();
        for (c, variant) in table.variants.iter().enumerate() {
            let Some(row) = best[c] else { continue };
            let radius = table.radii[row];
            // The best radius's cell of the lowest error among its seeds.
            let Some(e) = entries
                .iter()
                .filter(|e| e.cell.variant == *variant && e.cell.options.radius == radius)
                .min_by(|a, b| {
                    let m = |e: &&Entry| {
                        let value = e.last.get(plan.metric);
                        value.map_or(f64::INFINITY, |v| plan.metric.as_error(v))
                    };
                    m(a).total_cmp(&m(b))
                })
            else {
                continue;
            };
            let (film, _) = exr::read_render(&e.cell.output)?;
            let name = format!("images/{}.png", e.cell.name);
            png::write_preview(&dir.join(&name), &film.mean(), film.width, film.height)?;
            let _ = writeln!(
                html,
                "<figure><a href=\"{link}\"><img src=\"{name}\" alt=\"{alt}\"></a><figcaption>\
                 {alt}{partial}<br>r = {r}<br>{spp} spp, {t:.1} s<br>{errors}</figcaption>\
                 </figure>",
                link = html_escape(&from_report(&e.cell.output, &plan.output)),
                alt = html_escape(variant),
                partial = if e.partial { " (partial)" } else { "" },
                r = radius_text(radius),
                spp = e.metadata.iterations,
                t = e.metadata.render_seconds,
                errors = Metric::ALL
                    .into_iter()
                    .filter_map(|m| Some(format!("{} {}", m.label(), short(e.last.get(m)?))))
                    .collect::<Vec<_>>()
                    .join("<br>"),
            );
        }
        html.push_str("</div>\n");
        if entries.is_empty() {
            html.push_str("<p>No cell of this view is rendered yet.</p></section>\n");
            continue;
        }
        for metric in Metric::ALL {
            if metric != plan.metric {
                table = Table::new(&entries, metric);
            }
            if table.is_empty() {
                continue;
            }
            let stem = format!("tables/{view}.{}", metric.name());
            let [csv, md, tex] = table_files(&table);
            for (ext, text) in [("csv", csv), ("md", md), ("tex", tex)] {
                write_text(&dir.join(format!("{stem}.{ext}")), &text)?;
            }
            let _ = writeln!(
                html,
                "{}<p>As <a href=\"{stem}.csv\">CSV</a>, <a href=\"{stem}.md\">Markdown</a>, \
                 <a href=\"{stem}.tex\">LaTeX</a>.</p>",
                table_html(
                    &table,
                    &format!("{} per radius (best bold)", metric.label()),
                ),
            );
        }
        write_charts(plan, &dir, &view, &entries, &mut html)?;
        html.push_str("</section>\n");
    }
    html.push_str("</body></html>\n");
    let index = dir.join("index.html");
    write_text(&index, &html)?;
    Ok(index)
}

/// The error-against-radius chart of a view and a convergence chart per variant.
fn write_charts(
    plan: &Plan,
    dir: &Path,
    view: &str,
    entries: &[Entry],
    html: &mut String,
) -> Result<(), BatchError> {
    let mut variants: Vec<&str> = Vec::new();
    for e in entries {
        if !variants.contains(&e.cell.variant.as_str()) {
            variants.push(&e.cell.variant);
        }
    }
    let against_radius: Vec<Chart> = Metric::ALL
        .into_iter()
        .map(|metric| Table::new(entries, metric))
        .filter(|table| !table.is_empty())
        .map(|table| {
            let metric = table.metric;
            Chart {
                title: format!("{view}: {} against radius", metric.error_label()),
                x_label: "radius".into(),
                y_label: metric.error_label().into(),
                series: table
                    .variants
                    .iter()
                    .enumerate()
                    .map(|(c, v)| ChartSeries {
                        label: v.clone(),
                        points: table
                            .radii
                            .iter()
                            .zip(&table.values)
                            .filter_map(|(r, row)| {
                                Some((f64::from((*r)?), metric.as_error(row[c]?)))
                            })
                            .collect(),
                    })
                    .filter(|s| !s.points.is_empty())
                    .collect(),
            }
        })
        .collect();
    if against_radius.iter().any(|c| !c.series.is_empty()) {
        let name = format!("charts/{view}.radius.png");
        draw_charts(&dir.join(&name), &against_radius)?;
        let _ = writeln!(
            html,
            "<h3>Error against radius</h3><img class=\"chart\" src=\"{name}\" alt=\"error against radius\">"
        );
    }
    html.push_str("<h3>Convergence</h3>\n");
    let metric = plan.metric;
    for variant in variants {
        let cells: Vec<&Entry> = entries
            .iter()
            .filter(|e| e.cell.variant == variant)
            .collect();
        let windows = cells[0].metadata.traces.clone();
        let charts: Vec<Chart> = (0..=windows.len())
            .map(|w| Chart {
                title: match w {
                    0 => format!("{variant}: whole image"),
                    w => format!("{variant}: trace window {}", windows[w - 1]),
                },
                x_label: "time [s]".into(),
                y_label: metric.error_label().into(),
                series: cells
                    .iter()
                    .filter(|e| e.metadata.traces == windows)
                    .map(|e| ChartSeries {
                        label: match e.cell.options.radius {
                            Some(r) if e.cell.options.seed != 0 => {
                                format!("r={r} seed {}", e.cell.options.seed)
                            }
                            Some(r) => format!("r={r}"),
                            None => e.cell.name.clone(),
                        },
                        points: e
                            .metadata
                            .errors
                            .iter()
                            .filter_map(|s| {
                                let value = if w == 0 {
                                    s.get(metric)
                                } else {
                                    s.window(w - 1, metric)
                                };
                                Some((s.seconds, metric.as_error(value?)))
                            })
                            .collect(),
                    })
                    .collect(),
            })
            // The trace windows hold MAE and RMSE only.
            .filter(|c| c.series.iter().any(|s| !s.points.is_empty()))
            .collect();
        let name = format!("charts/{view}.{variant}.convergence.png");
        draw_charts(&dir.join(&name), &charts)?;
        let _ = writeln!(
            html,
            "<img class=\"chart\" src=\"{}\" alt=\"convergence of {}\">",
            html_escape(&name),
            html_escape(variant)
        );
    }
    Ok(())
}
