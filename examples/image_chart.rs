//! Draws the image fits' chart from the CSV `scripts/image-chart.sh` writes (columns
//! `image,pixels,method,light,seconds,median,p90,p99,max`, one row per run and light):
//!
//! ```text
//! cargo run --release --example image_chart -- fits/images/chart.csv fits/images/chart.png
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use fluorite::plot::ImageFormat;
use fluorite::plot::image_chart::{ImageChartPoint, image_chart};

fn read(path: &PathBuf) -> Result<Vec<ImageChartPoint>, String> {
    let mut reader =
        csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let headers = reader
        .headers()
        .map_err(|e| format!("{}: {e}", path.display()))?
        .clone();
    let column = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("{}: no column {name}", path.display()))
    };
    let (image, method, light) = (column("image")?, column("method")?, column("light")?);
    let (seconds, median, p99) = (column("seconds")?, column("median")?, column("p99")?);
    let mut points = Vec::new();
    for (line, record) in reader.records().enumerate() {
        let record = record.map_err(|e| format!("{}: {e}", path.display()))?;
        let number = |k: usize| -> Result<f64, String> {
            let text = record.get(k).unwrap_or("");
            if text.is_empty() || text == "null" {
                return Ok(f64::NAN);
            }
            text.parse()
                .map_err(|_| format!("{}:{}: {text} is not a number", path.display(), line + 2))
        };
        points.push(ImageChartPoint {
            image: record.get(image).unwrap_or("").to_string(),
            method: record.get(method).unwrap_or("").to_string(),
            light: record.get(light).unwrap_or("").to_string(),
            seconds: number(seconds)?,
            median: number(median)?,
            p99: number(p99)?,
        });
    }
    Ok(points)
}

fn main() -> ExitCode {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [csv, png] = args.as_slice() else {
        eprintln!("usage: image_chart CHART.csv CHART.png");
        return ExitCode::from(2);
    };
    let result = read(csv).and_then(|points| {
        let bytes = image_chart(&points, ImageFormat::Png).map_err(|e| e.to_string())?;
        fluorite::files::write_atomic(png, &bytes).map_err(|e| e.to_string())
    });
    match result {
        Ok(()) => {
            println!("wrote {}", png.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("image_chart: {e}");
            ExitCode::FAILURE
        }
    }
}
