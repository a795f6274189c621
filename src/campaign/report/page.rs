//! `report.html`: the summary table with each cell's replays, the pairs' own physics, and the
//! figures.

use super::MANIFOLD_FIGURE;

use crate::campaign::replays::{self, ReplayLink};
use crate::campaign::scenario::Scenario;
use crate::campaign::summary::{AXES, MeanStd, Summary};

/// `s` safe as HTML text.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

pub(super) fn html(
    scenario: &Scenario,
    summary: &Summary,
    replay_links: &[ReplayLink],
    manifolds: &[String],
    clearances_mm: &[f64],
    extra: Extras,
) -> String {
    let rows = table_rows(summary, replay_links);
    let axes: String = AXES.iter().map(|a| format!("<th>MAE {a}</th>")).collect();
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>pegtwin: {name}</title>\n<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:3px 7px;text-align:right}}</style></head><body>\n<h1>pegtwin campaign: {name}</h1>\n<p>Scenario fingerprint {fp}; {n} trials per cell; hole offsets U(-{om}, {om}) mm and U(-{od}, {od}) deg; success when the final depth is within {sm} mm of the floor.</p>\n{pp}<table><tr><th>geometry</th><th>clearance mm</th><th>method</th><th>t_obs s</th><th>success</th><th>95 % CI</th>{axes}<th>peak Fz success N</th><th>peak Fz failure N</th><th>partial to full insertion s (successes)</th><th title=\"failures that inserted: the jam break fired / the seat break fired above the floor / the target ran out with the peg held short of it\">failures jam / stall / wedge</th><th>replays</th></tr>\n{rows}</table>\n{coverage}{figures}{rp}</body></html>\n",
        name = escape(&scenario.name),
        fp = summary.fingerprint,
        n = scenario.trials,
        om = scenario.offset_mm,
        od = scenario.offset_deg,
        sm = scenario.success_mm,
        pp = pair_physics_html(scenario),
        coverage = extra.coverage_table,
        figures = figures_html(manifolds, clearances_mm, &extra),
        rp = replays::section(replay_links, &scenario.cells()),
    )
}

/// One table row per cell (with its replay links) and per pooled row.
pub(super) fn table_rows(summary: &Summary, replay_links: &[ReplayLink]) -> String {
    let mut rows = String::new();
    let indexed = summary.cells.iter().enumerate().map(|(i, c)| (Some(i), c));
    for (index, c) in indexed.chain(summary.pooled.iter().map(|c| (None, c))) {
        let mae = |a: usize| c.mae.map_or(String::new(), |m| format!("{:.2}", m[a]));
        let fz =
            |m: Option<MeanStd>| m.map_or("-".into(), |m| format!("{:.1} ± {:.1}", m.mean, m.std));
        rows += &format!(
            "<tr><td>{}</td><td>{}</td><td>{:?}</td><td>{}</td><td>{}/{}</td><td>{:.0}-{:.0} %</td>{}<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            escape(&c.cell.geometry),
            c.cell.clearance_mm,
            c.cell.method,
            c.cell.t_obs_s,
            c.successes,
            c.trials,
            c.success_ci95[0] * 100.0,
            c.success_ci95[1] * 100.0,
            (0..6)
                .map(|a| format!("<td>{}</td>", mae(a)))
                .collect::<String>(),
            fz(c.peak_fz_success_n),
            fz(c.peak_fz_failure_n),
            c.partial_to_full_s
                .map_or("-".into(), |m| format!("{:.1} ± {:.1}", m.mean, m.std)),
            {
                let f = c.failure_modes;
                format!("{} / {} / {}", f.jam, f.stall, f.wedge)
            },
            index.map_or(String::new(), |i| replays::cell_link(replay_links, i)),
        );
    }
    rows
}

/// The pairs that ran their own physics (`[[pair_physics]]`), so that a reader of the table
/// knows which rows were simulated differently; empty when none did.
pub(super) fn pair_physics_html(scenario: &Scenario) -> String {
    let items: Vec<String> = scenario
        .pair_physics
        .iter()
        .map(|o| {
            let at = o
                .clearance_mm
                .map_or("every clearance".into(), |c| format!("{c} mm"));
            let set = toml::to_string(&o.physics).expect("physics overrides serialise");
            let set = set.trim().replace('\n', ", ");
            format!("{} at {at}: {}", escape(&o.geometry), escape(&set))
        })
        .collect();
    if items.is_empty() {
        return String::new();
    }
    format!(
        "<p>Physics of their own (<code>[[pair_physics]]</code>, over the scenario's): {}.</p>\n",
        items.join("; ")
    )
}

/// What a campaign shows only when it has it.
#[derive(Clone, Debug)]
pub(super) struct Extras {
    /// The coverage table (HTML; empty without estimates and their standard deviations).
    pub(super) coverage_table: String,
    /// `fig7_coverage`: trials with an estimate and its standard deviations.
    pub(super) coverage: bool,
    /// `fig8_time`: cells of the adaptive method.
    pub(super) time: bool,
}

/// The paper's figures pooled, per clearance, the extra ones and the reference manifolds'.
pub(super) fn figures_html(manifolds: &[String], clearances_mm: &[f64], extra: &Extras) -> String {
    let figure = |name: &str, caption: &str| {
        format!(
            "<figure><img src=\"figures/{name}.png\" alt=\"{caption}\" width=\"960\"><figcaption>{caption} (<a href=\"figures/{name}.svg\">SVG</a>)</figcaption></figure>\n"
        )
    };
    let mut out = figure(
        "fig4_success",
        "Success rate per geometry, method vs direct (paper Fig. 4)",
    );
    out += &figure(
        "fig5_errors",
        "Success rate against position and orientation error (paper Fig. 5)",
    );
    out += &figure(
        "fig6_fz",
        "|Fz| profiles during insertion, success and failure, method vs direct (paper Fig. 6)",
    );
    for c in clearances_mm {
        out += &figure(
            &format!("fig5_errors-{c}mm"),
            &format!("Success rate against the estimate's errors at {c} mm (Fig. 5)"),
        );
        out += &figure(
            &format!("fig6_fz-{c}mm"),
            &format!("|Fz| profiles during insertion at {c} mm (Fig. 6)"),
        );
    }
    if extra.coverage {
        out += &figure(
            "fig7_coverage",
            "The estimate's error over its estimated standard deviation, per axis",
        );
    }
    if extra.time {
        out += &figure(
            "fig8_time",
            "Success against mean observation time: fixed t_obs and adaptive, per pair and pooled",
        );
    }
    for name in manifolds {
        out += &figure(
            name,
            &format!(
                "The reference contact manifold, {} (paper IV-B)",
                &name[MANIFOLD_FIGURE.len()..]
            ),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_names_the_pairs_with_physics_of_their_own() {
        let text = r#"
name = "t"
trials = 1
geometries = ["cross", "gear"]
clearances_mm = [0.1]
t_obs_s = [6.0]
methods = ["manifold"]
"#;
        let plain = Scenario::parse(text).unwrap();
        assert_eq!(pair_physics_html(&plain), "");
        let own = format!(
            "{text}\n[[pair_physics]]\ngeometry = \"gear\"\n\
             physics = {{ pgs_iterations = 8, friction = 0.2 }}\n"
        );
        let html = pair_physics_html(&Scenario::parse(&own).unwrap());
        assert!(
            html.contains("gear at every clearance: pgs_iterations = 8, friction = 0.2."),
            "{html}"
        );
    }
}
