//! The lenient reader: a material file as found, without invariants (non-numbers become
//! NaN, spectra may be unsorted or of unequal length), so every law can be evaluated on
//! broken files too.

use super::*;

/// A spectrum as found in the file, without any invariant (NaN for non-numbers).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawSpectrum {
    /// Wavelengths as written.
    pub wavelength_nm: Vec<f64>,
    /// Values as written.
    pub value: Vec<f64>,
}

/// A fluorophore as found in the file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawFluorophore {
    /// c (NaN when not a number).
    pub concentration: f64,
    /// The form's yield: Q (`quantum_yield`) in the energy form, Φ (`photon_yield`) in
    /// the photon form; NaN when not a number, missing, or given under the other form's
    /// key (then `yield_issues` says so).
    pub quantum_yield: f64,
    /// The yield form (`yield_form`; energy when absent or not understood).
    pub yield_form: YieldForm,
    /// How the yield is given wrongly (a photon-form fluorophore without `photon_yield`
    /// or with `quantum_yield`, an unknown `yield_form`, …): reported by
    /// [`Law::QuantumYieldRange`].
    pub yield_issues: Vec<String>,
    /// a(λ).
    pub absorption: RawSpectrum,
    /// e(λ).
    pub emission: RawSpectrum,
}

/// The `forms` block as found in the file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawForms {
    /// The model name as written (empty when missing).
    pub model: String,
    /// The forms, when the block reads as [`MaterialForms`].
    pub forms: Option<MaterialForms>,
    /// Why the block does not read, when it does not.
    pub error: Option<String>,
}

/// A material as found in the file: the shape of [`Material`] without its invariants.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawMaterial {
    /// The schema tag as written.
    pub schema: String,
    /// The name as written.
    pub name: String,
    /// r(λ).
    pub reflectance: RawSpectrum,
    /// The fluorophores.
    pub fluorophores: Vec<RawFluorophore>,
    /// The continuous forms, when the file has a `forms` block.
    pub forms: Option<RawForms>,
}

impl From<&Spectrum> for RawSpectrum {
    fn from(s: &Spectrum) -> Self {
        RawSpectrum {
            wavelength_nm: s.wavelength_nm.clone(),
            value: s.value.clone(),
        }
    }
}

impl From<&Material> for RawMaterial {
    fn from(m: &Material) -> Self {
        RawMaterial {
            schema: m.schema.clone(),
            name: m.name.clone(),
            reflectance: (&m.reflectance).into(),
            fluorophores: m
                .fluorophores
                .iter()
                .map(|f| RawFluorophore {
                    concentration: f.concentration,
                    quantum_yield: f.quantum_yield,
                    yield_form: f.yield_form,
                    yield_issues: Vec::new(),
                    absorption: (&f.absorption).into(),
                    emission: (&f.emission).into(),
                })
                .collect(),
            forms: m.forms.as_ref().map(|f| RawForms {
                model: f.model.clone(),
                forms: Some(f.clone()),
                error: None,
            }),
        }
    }
}

impl RawMaterial {
    /// Reads a material leniently from JSON text. Fails only when the text is not JSON or
    /// lacks the material's structure (`reflectance`, `fluorophores`, spectra with
    /// `wavelength_nm` and `value` arrays, `concentration`); values that are not numbers
    /// (null, strings) are read as NaN and reported by the check. A yield given wrongly
    /// for its form (missing, under the other form's key, an unknown `yield_form`) is
    /// reported by the check too, never guessed.
    pub fn from_json(text: &str, path: &Path) -> Result<RawMaterial> {
        let root: Value = serde_json::from_str(text)
            .map_err(|e| Error::parse(path, e.line(), e.column(), format!("not JSON: {e}")))?;
        let missing = |what: &str, fix: &str| {
            Error::parse(
                path,
                0,
                0,
                format!("not a fluorite material: {what}; {fix}"),
            )
        };
        let obj = root.as_object().ok_or_else(|| {
            missing(
                "the top level is not an object",
                "a material is a JSON object with reflectance and fluorophores",
            )
        })?;
        let schema = obj
            .get("schema")
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_string();
        let name = obj
            .get("name")
            .and_then(Value::as_str)
            .map(str::to_string)
            .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "material".to_string());
        let spectrum = |v: Option<&Value>, what: &str| -> Result<RawSpectrum> {
            let v = v.and_then(Value::as_object).ok_or_else(|| {
                missing(
                    &format!("{what} is missing or not an object"),
                    "give it as {\"wavelength_nm\": [...], \"value\": [...]}",
                )
            })?;
            let array = |key: &str| -> Result<Vec<f64>> {
                let a = v.get(key).and_then(Value::as_array).ok_or_else(|| {
                    missing(
                        &format!("{what}.{key} is missing or not an array"),
                        "give an array of numbers",
                    )
                })?;
                Ok(a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
            };
            Ok(RawSpectrum {
                wavelength_nm: array("wavelength_nm")?,
                value: array("value")?,
            })
        };
        if schema == crate::material::SHAPES_SCHEMA {
            return Err(missing(
                "it is a shapes-only fit (fluorite-fluorophore/1: absorption and emission without reflectance, c or Q)",
                "build a material from its spectra with `fluorite import-spectra`",
            ));
        }
        let reflectance = spectrum(obj.get("reflectance"), "reflectance")?;
        let list = obj
            .get("fluorophores")
            .and_then(Value::as_array)
            .ok_or_else(|| {
                missing(
                    "fluorophores is missing or not an array",
                    "give [] for a plain reflector",
                )
            })?;
        let mut fluorophores = Vec::new();
        for (n, f) in list.iter().enumerate() {
            let p = format!("fluorophores[{n}]");
            let scalar = |key: &str| -> Result<f64> {
                let v = f.get(key).ok_or_else(|| {
                    missing(&format!("{p}.{key} is missing"), "give a number in [0, 1]")
                })?;
                Ok(v.as_f64().unwrap_or(f64::NAN))
            };
            let (yield_form, quantum_yield, yield_issues) = raw_yield(f, &p);
            fluorophores.push(RawFluorophore {
                concentration: scalar("concentration")?,
                quantum_yield,
                yield_form,
                yield_issues,
                absorption: spectrum(f.get("absorption"), &format!("{p}.absorption"))?,
                emission: spectrum(f.get("emission"), &format!("{p}.emission"))?,
            });
        }
        // A malformed forms block is a broken law (reported), not an unreadable file.
        let forms = obj.get("forms").filter(|v| !v.is_null()).map(|v| {
            let model = v
                .get("model")
                .and_then(Value::as_str)
                .unwrap_or("")
                .to_string();
            match serde_json::from_value::<MaterialForms>(v.clone()) {
                Ok(forms) => RawForms {
                    model,
                    forms: Some(forms),
                    error: None,
                },
                Err(e) => RawForms {
                    model,
                    forms: None,
                    error: Some(e.to_string()),
                },
            }
        });
        Ok(RawMaterial {
            schema,
            name,
            reflectance,
            fluorophores,
            forms,
        })
    }
}

/// The yield form and the form's yield of a fluorophore object `f` (named `p`), with
/// every way they are given wrongly in words (the yield is then NaN: not guessed).
fn raw_yield(f: &Value, p: &str) -> (YieldForm, f64, Vec<String>) {
    let number = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    let q = f.get("quantum_yield").filter(|v| !v.is_null());
    let phi = f.get("photon_yield").filter(|v| !v.is_null());
    let mut issues = Vec::new();
    let form = match f.get("yield_form").filter(|v| !v.is_null()) {
        None => Some(YieldForm::Energy),
        Some(v) => match v.as_str() {
            Some("energy") => Some(YieldForm::Energy),
            Some("photon") => Some(YieldForm::Photon),
            _ => {
                issues.push(format!(
                    "{p}.yield_form is {v}; give \"energy\" (constant energy yield, `quantum_yield`; the default) or \"photon\" (constant photon yield, `photon_yield`)"
                ));
                None
            }
        },
    };
    let value = match (form, q, phi) {
        (None, _, _) => f64::NAN,
        (Some(YieldForm::Energy), Some(q), None) => number(q),
        (Some(YieldForm::Energy), q, Some(_)) => {
            issues.push(format!(
                "{p} gives `photon_yield` without \"yield_form\": \"photon\"; add that to make it a photon-form fluorophore{}",
                if q.is_some() {
                    " and drop `quantum_yield` (a fluorophore has one yield)"
                } else {
                    ", or give the energy yield as `quantum_yield`"
                }
            ));
            f64::NAN
        }
        (Some(YieldForm::Energy), None, None) => {
            issues.push(format!(
                "{p}.quantum_yield is missing; give the energy quantum yield Q in [0, 1] (or \"yield_form\": \"photon\" with `photon_yield` Φ)"
            ));
            f64::NAN
        }
        (Some(YieldForm::Photon), None, Some(phi)) => number(phi),
        (Some(YieldForm::Photon), Some(_), phi) => {
            issues.push(format!(
                "{p} has \"yield_form\": \"photon\" but gives `quantum_yield`; a photon-form fluorophore gives its photon yield Φ as `photon_yield` only{}",
                if phi.is_some() {
                    " (drop `quantum_yield`)"
                } else {
                    " (rename it if it is Φ, or drop yield_form if it is the energy yield Q)"
                }
            ));
            f64::NAN
        }
        (Some(YieldForm::Photon), None, None) => {
            issues.push(format!(
                "{p}.photon_yield is missing; a photon-form fluorophore needs its photon quantum yield Φ in [0, 1]"
            ));
            f64::NAN
        }
    };
    (form.unwrap_or_default(), value, issues)
}
