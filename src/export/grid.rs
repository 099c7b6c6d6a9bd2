//! Wavelength grids given on the command line.

use crate::error::{Error, Result};

/// Parses a grid: comma-separated segments, each `start:end:step` (inclusive) or a
/// single wavelength, in nm, e.g. `300:780:5` or `300:400:10,405:780:5`. The segments
/// must not overlap: the whole grid strictly increases. `parameter` names the option in
/// errors (`--grid`).
pub fn parse_grid(text: &str, parameter: &str) -> Result<Vec<f64>> {
    let bad = |message: String| Error::invalid(parameter, message);
    const HELP: &str = "give start:end:step in nm (e.g. 300:780:5) or comma-separated wavelengths";
    if text.trim().is_empty() {
        return Err(bad(format!("is empty; {HELP}")));
    }
    let mut grid: Vec<f64> = Vec::new();
    for (n, segment) in text.split(',').enumerate() {
        let segment = segment.trim();
        let number = |s: &str, what: &str| -> Result<f64> {
            let v: f64 = s.trim().parse().map_err(|_| {
                bad(format!(
                    "{what} \"{s}\" of segment {} (\"{segment}\") is not a number; {HELP}",
                    n + 1
                ))
            })?;
            if !v.is_finite() {
                return Err(bad(format!("{what} is {v}; {HELP}")));
            }
            Ok(v)
        };
        let fields: Vec<&str> = segment.split(':').collect();
        let points = match fields.as_slice() {
            [single] => vec![number(single, "wavelength")?],
            [start, end, step] => {
                let (start, end, step) = (
                    number(start, "start")?,
                    number(end, "end")?,
                    number(step, "step")?,
                );
                if step <= 0.0 {
                    return Err(bad(format!(
                        "step {step} of \"{segment}\" must be positive; {HELP}"
                    )));
                }
                if end < start {
                    return Err(bad(format!(
                        "\"{segment}\" is empty: end {end} nm lies below start {start} nm"
                    )));
                }
                let intervals = (end - start) / step;
                let n = intervals.round();
                if (intervals - n).abs() > 1e-6 * n.max(1.0) {
                    return Err(bad(format!(
                        "\"{segment}\": end {end} nm is not start plus a whole number of steps of {step} nm; end at {} or {} nm",
                        start + step * intervals.floor(),
                        start + step * intervals.ceil()
                    )));
                }
                if n > 1e6 {
                    return Err(bad(format!(
                        "\"{segment}\" has {n} samples; use a coarser step"
                    )));
                }
                // Computed from the start, not accumulated, so samples land on exact values.
                (0..=n as usize).map(|i| start + step * i as f64).collect()
            }
            _ => {
                return Err(bad(format!(
                    "segment \"{segment}\" is neither a wavelength nor start:end:step; {HELP}"
                )));
            }
        };
        if let (Some(&last), Some(&first)) = (grid.last(), points.first())
            && first <= last
        {
            return Err(bad(format!(
                "segment \"{segment}\" starts at {first} nm, overlapping the previous segments which reach {last} nm; segments must increase without overlap"
            )));
        }
        grid.extend(points);
    }
    if let Some(&l) = grid.iter().find(|&&l| l <= 0.0) {
        return Err(bad(format!("holds {l} nm; wavelengths must be positive")));
    }
    Ok(grid)
}

#[cfg(test)]
mod tests {
    use super::parse_grid;

    #[test]
    fn grids_parse_and_bad_ones_are_named() {
        let g = parse_grid("300:780:5", "--grid").unwrap();
        assert_eq!(g.len(), 97);
        assert_eq!(g[96], 780.0);
        assert_eq!(
            parse_grid("300:320:10,325,330:340:10", "--grid").unwrap(),
            vec![300.0, 310.0, 320.0, 325.0, 330.0, 340.0]
        );
        for bad in [
            "",
            "300:780",
            "a:b:c",
            "300:780:0",
            "780:300:5",
            "300:400:10,400:500:10",
            "300:785:10",
            "-5:10:5",
        ] {
            let e = parse_grid(bad, "--grid").unwrap_err().to_string();
            assert!(e.starts_with("--grid: "), "{bad}: {e}");
        }
    }
}
