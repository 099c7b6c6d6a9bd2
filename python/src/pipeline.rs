//! TEMPORARY stand-in for `fluorite::pipeline` and `fluorite::render::picture` (the API
//! the lead is moving into the library on main), so that the bindings build and test
//! before it lands. Replaced by the library's modules at the merge.
#![allow(dead_code)]

pub mod input {
    use std::path::{Path, PathBuf};

    use fluorite::eem::correct::Absorbance;
    use fluorite::eem::scatter::{ScatterLine, ScatterOptions, WATER_RAMAN_SHIFT_CM};
    use fluorite::eem::{EemOptions, Preprocessing, UnitsChoice, prepare};
    use fluorite::formats::{ReadOptions, read};
    use fluorite::{Error, Measurement, Result};

    #[derive(Debug, Clone)]
    pub struct EemSettings {
        pub units: UnitsChoice,
        pub blank: Vec<PathBuf>,
        pub absorbance: Vec<PathBuf>,
        pub keep_scatter: bool,
        pub scatter_half_width_nm: [Option<f64>; 4],
        pub bandwidth_nm: Option<f64>,
        pub raman_shift_cm: f64,
    }

    impl Default for EemSettings {
        fn default() -> Self {
            EemSettings {
                units: UnitsChoice::Auto,
                blank: Vec::new(),
                absorbance: Vec::new(),
                keep_scatter: false,
                scatter_half_width_nm: [None; 4],
                bandwidth_nm: None,
                raman_shift_cm: WATER_RAMAN_SHIFT_CM,
            }
        }
    }

    impl EemSettings {
        pub fn set_scatter_width(&mut self, line: &str, nm: f64) -> Result<()> {
            let line = line.trim().to_ascii_lowercase();
            let mut matched = false;
            for (k, l) in ScatterLine::ALL.iter().enumerate() {
                if line == "all" || line == l.name() {
                    self.scatter_half_width_nm[k] = Some(nm);
                    matched = true;
                }
            }
            if !matched {
                return Err(Error::invalid(
                    format!("--scatter-width {line}={nm}"),
                    format!(
                        "unknown line {line:?}; use rayleigh1, raman1, rayleigh2, raman2 or all"
                    ),
                ));
            }
            Ok(())
        }
    }

    #[derive(Debug, Clone, Default)]
    pub struct InputOptions {
        pub read: ReadOptions,
        pub eem: EemSettings,
    }

    #[derive(Debug, Clone)]
    pub struct Prepared {
        pub measurement: Measurement,
        pub preprocessing: Option<Preprocessing>,
    }

    pub fn read_input(
        path: &Path,
        index: usize,
        count: usize,
        options: &InputOptions,
    ) -> Result<Prepared> {
        let eem = &options.eem;
        let pick = |files: &[PathBuf], what: &str, shared: bool| -> Result<Option<PathBuf>> {
            match files.len() {
                0 => Ok(None),
                1 if shared || count == 1 => Ok(Some(files[0].clone())),
                n if n == count => Ok(Some(files[index].clone())),
                n => Err(Error::invalid(
                    format!("--{what}"),
                    format!("{n} files for {count} inputs"),
                )),
            }
        };
        let blank = match pick(&eem.blank, "blank", true)? {
            Some(p) => Some((read(&p, &options.read)?, p)),
            None => None,
        };
        let absorbance = match pick(&eem.absorbance, "absorbance", false)? {
            Some(p) => Some((Absorbance::read(&p)?, p)),
            None => None,
        };
        let eem_options = EemOptions {
            units: eem.units,
            zero_is_missing: options.read.zero_is_missing,
            blank,
            absorbance,
            keep_scatter: eem.keep_scatter,
            scatter: ScatterOptions {
                half_width_nm: eem.scatter_half_width_nm,
                bandwidth_nm: eem.bandwidth_nm,
                raman_shift_cm: Some(eem.raman_shift_cm),
            },
        };
        let m = read(path, &options.read)?;
        let (measurement, preprocessing) = prepare(m, &eem_options)?;
        Ok(Prepared {
            measurement,
            preprocessing,
        })
    }
}

pub mod single {
    use std::path::Path;

    use fluorite::fit::{FitOptions, FitOutcome, fit};
    use fluorite::{Measurement, Result};

    use super::input::{InputOptions, Prepared, read_input};

    pub struct Fitted {
        pub measurement: Measurement,
        pub outcome: FitOutcome,
    }

    pub fn fit_prepared(prepared: &Prepared, options: &FitOptions) -> Result<FitOutcome> {
        let mut outcome = fit(&prepared.measurement, options)?;
        if let Some(p) = &prepared.preprocessing {
            outcome.record_preprocessing(p.clone());
        }
        Ok(outcome)
    }

    pub fn fit_file(
        path: &Path,
        index: usize,
        count: usize,
        input: &InputOptions,
        options: &FitOptions,
    ) -> Result<Fitted> {
        let prepared = read_input(path, index, count, input)?;
        let outcome = fit_prepared(&prepared, options)?;
        Ok(Fitted {
            measurement: prepared.measurement,
            outcome,
        })
    }

    pub fn fit_many(
        inputs: &[Prepared],
        options: &FitOptions,
        threads: Option<usize>,
    ) -> Vec<Result<FitOutcome>> {
        use rayon::prelude::*;
        let run = || {
            inputs
                .par_iter()
                .map(|p| fit_prepared(p, options))
                .collect::<Vec<_>>()
        };
        match threads {
            None => run(),
            Some(n) => match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
                Ok(pool) => pool.install(run),
                Err(e) => vec![Err(fluorite::Error::invalid("threads", e.to_string()))],
            },
        }
    }
}

pub mod joint {
    use std::path::{Path, PathBuf};

    use fluorite::colour::Light;
    use fluorite::fit::YieldChoice;
    use fluorite::fit::joint::parafac::ParafacOptions;
    use fluorite::fit::joint::reference::{AnalyteMatch, Reference};
    use fluorite::fit::joint::{JointFit, JointOptions, fit_joint};
    use fluorite::fit::series::{SeriesFit, SeriesOptions, fit_concentration_series};
    use fluorite::{Error, Result};

    use super::input::Prepared;

    #[derive(Debug, Clone)]
    pub struct JointRequest {
        pub components: Vec<usize>,
        pub em_range: Option<(f64, f64)>,
        pub ex_range: Option<(f64, f64)>,
        pub no_split_half: bool,
        pub max_iterations: u64,
        pub yield_choice: YieldChoice,
        pub guard_nm: Option<f64>,
        pub lights: Vec<Light>,
        pub timing_runs: usize,
        pub reference: Option<Reference>,
    }

    impl Default for JointRequest {
        fn default() -> Self {
            JointRequest {
                components: Vec::new(),
                em_range: None,
                ex_range: None,
                no_split_half: false,
                max_iterations: 500,
                yield_choice: YieldChoice::Auto,
                guard_nm: None,
                lights: Light::standard(),
                timing_runs: 1,
                reference: None,
            }
        }
    }

    pub enum JointOutcome {
        Series(Box<SeriesFit>),
        Eem(Vec<EemFit>),
    }

    pub struct EemFit {
        pub fit: JointFit,
        pub matches: Option<Vec<AnalyteMatch>>,
    }

    pub fn fit_samples(samples: &[Prepared], request: &JointRequest) -> Result<JointOutcome> {
        let eems: Vec<_> = samples
            .iter()
            .filter(|p| p.preprocessing.is_some())
            .map(|p| p.measurement.clone())
            .collect();
        let surfaces: Vec<_> = samples
            .iter()
            .filter(|p| p.preprocessing.is_none())
            .map(|p| p.measurement.clone())
            .collect();
        if !eems.is_empty() && !surfaces.is_empty() {
            return Err(Error::invalid(
                "joint fit",
                "a joint fit needs one kind of matrix",
            ));
        }
        if !surfaces.is_empty() {
            let options = SeriesOptions {
                yield_choice: request.yield_choice,
                guard_nm: request.guard_nm,
                max_iterations: request.max_iterations,
                lights: request.lights.clone(),
                ..Default::default()
            };
            return Ok(JointOutcome::Series(Box::new(fit_concentration_series(
                &surfaces, &options,
            )?)));
        }
        let ks = if request.components.is_empty() {
            vec![ParafacOptions::default().components]
        } else {
            request.components.clone()
        };
        let mut fits = Vec::new();
        for k in ks {
            let options = JointOptions {
                parafac: ParafacOptions {
                    components: k,
                    max_iterations: request.max_iterations.max(1) as usize,
                    ..ParafacOptions::default()
                },
                em_range: request.em_range,
                ex_range: request.ex_range,
                no_split_half: request.no_split_half,
            };
            let fit = fit_joint(&eems, &options)?;
            let matches = request.reference.as_ref().map(|r| r.best_matches(&fit));
            fits.push(EemFit { fit, matches });
        }
        Ok(JointOutcome::Eem(fits))
    }

    impl JointOutcome {
        pub fn write(&self, out: &Path) -> Result<Vec<PathBuf>> {
            match self {
                JointOutcome::Series(s) => s.write(out, "series"),
                JointOutcome::Eem(fits) => {
                    let mut written = Vec::new();
                    for f in fits {
                        let dir = if fits.len() > 1 {
                            out.join(format!("k{}", f.fit.components.len()))
                        } else {
                            out.to_path_buf()
                        };
                        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
                        let files = f.fit.files(&dir);
                        fluorite::files::write_files(&files)?;
                        written.extend(files.into_iter().map(|(p, _)| p));
                    }
                    Ok(written)
                }
            }
        }
    }
}

pub mod picture {
    use std::time::Instant;

    use fluorite::colour::Light;
    use fluorite::render::image::{film_to_linear_srgb, to_srgb8, xyz_to_srgb_matrix};
    use fluorite::render::{
        DEFAULT_EXPOSURE_EV, RenderSettings, Scene, SceneKind, SpectralSampling, render,
    };
    use fluorite::{Material, Result};

    pub struct Picture {
        pub light: Light,
        pub settings: RenderSettings,
        pub kind: SceneKind,
        pub compare: bool,
        pub sampling: SpectralSampling,
        pub exposure_ev: Option<f64>,
        pub adapt: bool,
    }

    pub struct Rendered {
        pub width: u32,
        pub height: u32,
        pub scene_linear: Vec<[f32; 3]>,
        pub display_srgb8: Vec<u8>,
        pub png: Vec<u8>,
        pub exposure_ev: f64,
        pub seconds: f64,
    }

    pub fn render_picture(
        material: &Material,
        picture: &Picture,
        on_row: &(dyn Fn() + Sync),
    ) -> Result<Rendered> {
        let settings = &picture.settings;
        settings.validate()?;
        let mut scene = Scene::build(
            picture.kind,
            material,
            &picture.light,
            picture.compare,
            settings.aspect(),
        )?;
        scene.set_spectral_sampling(picture.sampling);
        let started = Instant::now();
        let film = render(&scene, settings, on_row)?;
        let seconds = started.elapsed().as_secs_f64();
        let ev = picture.exposure_ev.unwrap_or(DEFAULT_EXPOSURE_EV);
        fluorite::render::image::check_exposure(ev)?;
        let scene_linear = film_to_linear_srgb(&film, &xyz_to_srgb_matrix(scene.light(), false));
        let display = film_to_linear_srgb(&film, &xyz_to_srgb_matrix(scene.light(), picture.adapt));
        let display_srgb8 = to_srgb8(&display, ev);
        let png = fluorite::render::image::encode_png(
            film.width,
            film.height,
            &display_srgb8,
            "fluorite render",
        )?;
        Ok(Rendered {
            width: film.width,
            height: film.height,
            scene_linear,
            display_srgb8,
            png,
            exposure_ev: ev,
            seconds,
        })
    }
}
