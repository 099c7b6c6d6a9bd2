//! Writing a synthetic image's files: the two bispectral images, the material map's
//! textures and JSON, and the generating parameters, each tile computed when the writer
//! asks for it.

use std::path::Path;
use std::sync::Mutex;

use crate::error::{Error, Result};
use crate::formats::exr::{VERSION, VERSION_ATTRIBUTE, diagonal_channel};
use crate::image::sink::{ImageSpec, Rect, TILE, write_image};

use super::colour::{CellColorimeter, Tally, noise_colorimeters};
use super::{ImageSynth, Written};

impl ImageSynth {
    /// Number of tiles of one image file.
    pub fn tiles(&self) -> usize {
        self.options.width.div_ceil(TILE) * self.options.height.div_ceil(TILE)
    }

    /// Writes every output into `dir` (created if missing): `NAME.exr` (with noise),
    /// `NAME.truth.exr`, `NAME.truth/{concentration.exr, reflectance.exr,
    /// material-map.json}` and `NAME.synth.json`. Each file is written whole or not at
    /// all. `progress(file, tiles done, tiles in all)` follows the four images' tiles.
    pub fn write(
        &self,
        dir: &Path,
        mut progress: impl FnMut(&Path, usize, usize),
    ) -> Result<Written> {
        let name = &self.options.name;
        let map_dir = dir.join(format!("{name}.truth"));
        std::fs::create_dir_all(&map_dir).map_err(|e| Error::io(&map_dir, e))?;
        let map = self.material_map();
        let noisy = dir.join(format!("{name}.exr"));
        let truth = dir.join(format!("{name}.truth.exr"));
        let concentration = map_dir.join(&map.textures.concentration);
        let reflectance = map_dir.join(&map.textures.reflectance);
        let tiles = self.tiles();
        let total = 4 * tiles;
        let spectral = vec![(VERSION_ATTRIBUTE.to_string(), VERSION.to_string())];
        let image_spec = |channels: Vec<String>, half: bool| ImageSpec {
            width: self.options.width,
            height: self.options.height,
            channels,
            half,
            zip: self.options.zip,
            attributes: spectral.clone(),
        };
        let cells = image_spec(self.layout.channel_names(), self.options.half);
        let colorimeters = noise_colorimeters(
            &self.layout,
            &self.options.excitation_nm,
            &self.options.emission_nm,
            &self.grid_of,
        )?;
        let tally = Mutex::new(Tally::new(colorimeters.len()));
        write_image(
            &noisy,
            &cells,
            |rect| self.noisy_tile(rect, &colorimeters, &tally),
            |done, _| progress(&noisy, done, total),
        )?;
        write_image(
            &truth,
            &cells,
            |rect| self.truth_tile(rect),
            |done, _| progress(&truth, tiles + done, total),
        )?;
        let k = self.fluorophores.len();
        let concentration_spec = ImageSpec {
            attributes: Vec::new(),
            ..image_spec(map.textures.concentration_channels.clone(), false)
        };
        write_image(
            &concentration,
            &concentration_spec,
            |rect| {
                self.tile(rect, k, |x, y, out| {
                    out.extend(self.concentrations(x, y));
                    Ok(())
                })
            },
            |done, _| progress(&concentration, 2 * tiles + done, total),
        )?;
        let reflectance_spec = image_spec(
            self.diagonal_nm
                .iter()
                .map(|&l| diagonal_channel(l))
                .collect(),
            false,
        );
        write_image(
            &reflectance,
            &reflectance_spec,
            |rect| {
                self.tile(rect, self.diagonal_nm.len(), |x, y, out| {
                    out.extend(self.pixel(x, y)?.reflectance);
                    Ok(())
                })
            },
            |done, _| progress(&reflectance, 3 * tiles + done, total),
        )?;
        let map_json = map_dir.join("material-map.json");
        crate::files::write_atomic(&map_json, map.to_json().as_bytes())?;
        let mut record = self.record();
        let names: Vec<String> = colorimeters.iter().map(|c| c.light.clone()).collect();
        let tally = tally.into_inner().unwrap_or_else(|e| e.into_inner());
        record.noise_delta_e2000 = tally.stats(&names);
        let record_json = dir.join(format!("{name}.synth.json"));
        let text = serde_json::to_string_pretty(&record).map_err(|e| {
            Error::io(
                &record_json,
                std::io::Error::other(format!("not serialisable: {e}")),
            )
        })? + "\n";
        crate::files::write_atomic(&record_json, text.as_bytes())?;
        Ok(Written {
            files: vec![
                noisy,
                truth,
                concentration,
                reflectance,
                map_json,
                record_json,
            ],
            record,
        })
    }

    /// The value a cell holds once stored (16-bit floats round further).
    fn stored(&self, v: f64) -> f32 {
        let f = v as f32;
        if self.options.half {
            exr::prelude::f16::from_f32(f).to_f32()
        } else {
            f
        }
    }

    /// The pixels of a rectangle, `per_pixel(x, y, out)` appending each one's values.
    fn tile(
        &self,
        rect: Rect,
        values_per_pixel: usize,
        mut per_pixel: impl FnMut(usize, usize, &mut Vec<f32>) -> Result<()>,
    ) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(rect.width * rect.height * values_per_pixel);
        for y in rect.y..rect.y + rect.height {
            for x in rect.x..rect.x + rect.width {
                per_pixel(x, y, &mut out)?;
            }
        }
        Ok(out)
    }

    fn truth_tile(&self, rect: Rect) -> Result<Vec<f32>> {
        let mut cells = vec![0.0; self.layout.len()];
        self.tile(rect, cells.len(), |x, y, out| {
            self.truth_cells(&self.pixel(x, y)?, &mut cells);
            out.extend(cells.iter().map(|&v| v as f32));
            Ok(())
        })
    }

    /// A tile of the noisy image; counts each pixel's ΔE2000 to its truth, as stored.
    fn noisy_tile(
        &self,
        rect: Rect,
        colorimeters: &[CellColorimeter],
        tally: &Mutex<Tally>,
    ) -> Result<Vec<f32>> {
        let n = self.layout.len();
        let mut cells = vec![0.0; n];
        let mut truth = vec![0f32; n];
        let mut noisy = vec![0f32; n];
        let mut local = Tally::new(colorimeters.len());
        let values = self.tile(rect, n, |x, y, out| {
            self.truth_cells(&self.pixel(x, y)?, &mut cells);
            for (t, &v) in truth.iter_mut().zip(&cells) {
                *t = self.stored(v);
            }
            self.add_noise(x, y, &mut cells);
            for (s, &v) in noisy.iter_mut().zip(&cells) {
                *s = self.stored(v);
            }
            for (light, c) in colorimeters.iter().enumerate() {
                local.add(light, c.delta_e(&truth, &noisy));
            }
            out.extend(cells.iter().map(|&v| v as f32));
            Ok(())
        })?;
        tally
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .merge(&local);
        Ok(values)
    }
}
