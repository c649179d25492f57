//! The bench's report: per-scene tables and CSV, the combined front, the sweeps around
//! the defaults, the shaping at 10 m.

use super::scenes::Scene;
use super::{
    CONES, Config, Errors, FIELDS, Row, SHAPINGS, SIZE, ao_image, configs, costs, dominates,
    errors, front,
};
use std::fmt::Write as _;

/// The per-scene table: appended to `md`, returned as CSV.
pub fn tables(rows: &[Row], md: &mut String) -> String {
    let header = "scene | cones | steps | divisor | shaping | bias (m) | distance evaluations / pixel | time (ms, one thread) | mean \\|ΔAO\\|, all | mean AO − truth, all | mean \\|ΔAO\\|, occluded | mean \\|ΔAO\\|, contact | occluded pixels | surface pixels | bent normal (rad), all | bent normal (rad), occluded | Pareto | default";
    let _ = writeln!(md, "| {header} |\n|{}", "---|".repeat(18));
    let mut csv = String::from(
        "scene,cones,steps,divisor,shaping,bias,evaluations_per_pixel,milliseconds,ao_error_all,\
         ao_signed_all,ao_error_occluded,ao_error_contact,occluded_pixels,surface_pixels,bent_error_all,bent_error_occluded,\
         pareto,default\n",
    );
    for r in rows {
        let (c, e) = (r.config, r.errors);
        let cells = [
            r.scene.clone(),
            c.cones.to_string(),
            c.steps.to_string(),
            c.divisor.to_string(),
            c.shaping.to_string(),
            c.bias.to_string(),
            format!("{:.2}", r.evaluations),
            format!("{:.2}", r.seconds * 1e3),
            format!("{:.4}", e.ao),
            format!("{:+.4}", e.signed),
            format!("{:.4}", e.ao_occluded),
            format!("{:.4}", e.ao_contact),
            e.occluded.to_string(),
            e.surface.to_string(),
            format!("{:.4}", e.bent),
            format!("{:.4}", e.bent_occluded),
        ];
        let (front, default) = (r.pareto, c == Config::DEFAULT);
        let _ = writeln!(
            md,
            "| {} | {} | {} |",
            cells.join(" | "),
            if front { "✓" } else { "" },
            if default { "default" } else { "" }
        );
        let _ = writeln!(csv, "{},{front},{default}", cells.join(","));
    }
    csv
}

/// Every scene: per configuration, the summed work and the means of the two errors (all
/// surface pixels), with the Pareto front.
pub fn combined(rows: &[Row], scenes: usize, md: &mut String) {
    let n = scenes.max(1) as f64;
    let table: Vec<(Config, [f64; 3])> = configs()
        .into_iter()
        .map(|c| {
            let sum = rows
                .iter()
                .filter(|r| r.config == c)
                .map(|r| costs(r.evaluations, &r.errors))
                .fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
            (c, [sum[0], sum[1] / n, sum[2] / n])
        })
        .collect();
    md.push_str(
        "\n## All scenes\n\nPer configuration: distance evaluations per pixel summed over the scenes, mean \\|ΔAO\\| and the bent normal's mean angle (all surface pixels) averaged over them. Pareto front (of the three, among the settable configurations) only, and the defaults.\n\n| cones | steps | divisor | shaping | bias (m) | evaluations / pixel (sum) | mean \\|ΔAO\\| | bent normal (rad) | Pareto | default |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (&(c, [work, error, bent]), on) in table.iter().zip(front(&table)) {
        if on || c == Config::DEFAULT {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {work:.1} | {error:.4} | {bent:.4} | {} | {} |",
                c.cones,
                c.steps,
                c.divisor,
                c.shaping,
                c.bias,
                if on { "✓" } else { "" },
                if c == Config::DEFAULT { "default" } else { "" }
            );
        }
    }
}

/// Per scene, one setting at a time around the defaults (the others at theirs), and the
/// check lines: the defaults' error against 0.08, and whether they are on the front.
pub fn around_defaults(rows: &[Row], names: &[String], md: &mut String) {
    md.push_str(
        "\n## Around the defaults\n\nOne setting varied, the others at the defaults: \
         `mean |ΔAO| (evaluations / pixel)`, ✓ on the scene's Pareto front.\n\n",
    );
    let only = |c: &Config, k: usize| {
        (0..FIELDS.len()).all(|j| j == k || c.fields()[j] == Config::DEFAULT.fields()[j])
    };
    for name in names {
        let _ = writeln!(md, "**{name}**\n");
        let scene: Vec<&Row> = rows.iter().filter(|r| &r.scene == name).collect();
        for (k, label) in FIELDS.iter().enumerate() {
            let mut line: Vec<&&Row> = scene.iter().filter(|r| only(&r.config, k)).collect();
            line.sort_by(|a, b| a.config.fields()[k].total_cmp(&b.config.fields()[k]));
            let cells: Vec<String> = line
                .iter()
                .map(|r| {
                    let default = if r.config == Config::DEFAULT {
                        " (default)"
                    } else {
                        ""
                    };
                    let front = if r.pareto { " ✓" } else { "" };
                    let (e, w) = (r.errors.ao, r.evaluations);
                    format!(
                        "{label} {}{default}: {e:.4} ({w:.0}){front}",
                        r.config.fields()[k]
                    )
                })
                .collect();
            let _ = writeln!(md, "- {}", cells.join("; "));
        }
        // The best shaping at each cone count (steps, divisor and bias at the defaults).
        let best: Vec<String> = CONES
            .iter()
            .filter_map(|&cones| {
                let at = |r: &&&Row| {
                    Config::around(|c| (c.cones, c.shaping) = (cones, r.config.shaping)) == r.config
                };
                let r = scene
                    .iter()
                    .filter(at)
                    .min_by(|a, b| a.errors.ao.total_cmp(&b.errors.ao))?;
                Some(format!(
                    "{cones} cones: {} ({:.4})",
                    r.config.shaping, r.errors.ao
                ))
            })
            .collect();
        let _ = writeln!(md, "- best shaping per cone count: {}", best.join("; "));
        let Some(d) = scene.iter().find(|r| r.config == Config::DEFAULT) else {
            continue;
        };
        let _ = writeln!(
            md,
            "\n{name}: defaults mean AO error {:.4} (≤ 0.08: {}); mean AO − truth {:+.4}, bent \
             normal {:.3} rad (occluded pixels), {:.0} evaluations / pixel, {:.1} ms",
            d.errors.ao,
            if d.errors.ao <= 0.08 { "yes" } else { "no" },
            d.errors.signed,
            d.errors.bent_occluded,
            d.evaluations,
            d.seconds * 1e3
        );
        if d.pareto {
            let _ = writeln!(md, "{name}: the defaults are on the Pareto front\n");
            continue;
        }
        let mut by: Vec<&&Row> = scene
            .iter()
            .filter(|r| {
                r.pareto
                    && dominates(
                        costs(r.evaluations, &r.errors),
                        costs(d.evaluations, &d.errors),
                    )
            })
            .collect();
        by.sort_by(|a, b| a.errors.ao.total_cmp(&b.errors.ao));
        let list: Vec<String> = by
            .iter()
            .take(3)
            .map(|r| {
                format!(
                    "{} ({:.4} at {:.0} evaluations / pixel)",
                    r.config.label(),
                    r.errors.ao,
                    r.evaluations
                )
            })
            .collect();
        let _ = writeln!(
            md,
            "{name}: the defaults are NOT on the Pareto front; dominated by {} front point(s), \
             the most accurate: {}\n",
            by.len(),
            list.join("; ")
        );
    }
}

/// The shaping sweep again (the other settings at the defaults) at the
/// component's default max distance, 10 m, against truth traced to 10 m.
pub fn at_ten_metres(builders: &[fn(f32) -> Option<Scene>], md: &mut String) {
    md.push_str("\n## Shaping at the component's 10 m max distance\n\n`shaping: mean |ΔAO| (mean AO − truth)`, all surface pixels; the defaults otherwise (9 cones, 8 steps, divisor 4, bias 0.02 m).\n\n");
    for build in builders {
        let Some(scene) = build(10.0) else { continue };
        let errors: Vec<(f32, Errors)> = SHAPINGS
            .iter()
            .map(|&shaping| {
                let (image, _) = ao_image(&scene, Config::around(|c| c.shaping = shaping), 0);
                (shaping, errors(&scene, &image))
            })
            .collect();
        let best = errors.iter().min_by(|a, b| a.1.ao.total_cmp(&b.1.ao));
        let cells: Vec<String> = errors
            .iter()
            .map(|(s, e)| format!("{s}: {:.4} ({:+.4})", e.ao, e.signed))
            .collect();
        let best = best.map_or(String::new(), |(s, e)| format!("; best {s} ({:.4})", e.ao));
        let _ = writeln!(md, "- {}: {}{best}", scene.name, cells.join("; "));
        // Cones, steps and divisor at this reach (a march of few steps may end before a
        // far occluder): `cones/steps/divisor: mean |ΔAO| (contact) [evaluations]`.
        let cells: Vec<String> = TEN_METRE_CONFIGS
            .iter()
            .map(|&(cones, steps, divisor)| {
                let config =
                    Config::around(|c| (c.cones, c.steps, c.divisor) = (cones, steps, divisor));
                let (image, evaluations) = ao_image(&scene, config, 0);
                let e = super::errors(&scene, &image);
                format!(
                    "{cones}/{steps}/{divisor}: {:.4} ({:.4}) [{:.1}]",
                    e.ao,
                    e.ao_contact,
                    evaluations as f64 / f64::from(SIZE * SIZE)
                )
            })
            .collect();
        let _ = writeln!(md, "  - {}", cells.join("; "));
    }
}

/// (cones, steps, divisor) compared at 10 m.
const TEN_METRE_CONFIGS: [(u32, u32, u32); 6] = [
    (9, 16, 2),
    (9, 8, 2),
    (9, 16, 4),
    (9, 8, 4),
    (16, 16, 4),
    (16, 8, 4),
];
