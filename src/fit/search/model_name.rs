//! Model names: `as-needed`, `tabulated`, `auto`, `gaussian:KxA/E[+rD|+rt][@wavelength][/photon]`.

use super::*;

impl FromStr for ModelChoice {
    type Err = Error;

    /// `as-needed`, `tabulated`, `auto`, or `gaussian:KxB` / `gaussian:KxA/E`, optionally followed by
    /// `+rD` (sigmoid-polynomial reflectance of degree D) or `+rt` (tabulated
    /// reflectance), `@wavenumber` / `@wavelength`, and `/photon` (components with a
    /// constant photon yield Φ; without it `--yield` decides).
    fn from_str(text: &str) -> Result<Self> {
        let bad = |why: &str| {
            Error::invalid(
                "--model",
                format!(
                    "\"{text}\" {why}; use as-needed, tabulated, auto, or gaussian:KxB[/E][+rD|+rt][@wavenumber|@wavelength][/photon] (e.g. gaussian:2x1, gaussian:1x2/1+r4, gaussian:1x1+r6/photon)"
                ),
            )
        };
        match text.trim() {
            "tabulated" => return Ok(ModelChoice::Tabulated),
            "as-needed" => return Ok(ModelChoice::AsNeeded),
            "auto" => return Ok(ModelChoice::Auto),
            _ => {}
        }
        let Some(rest) = text.trim().strip_prefix("gaussian:") else {
            return Err(bad("is not a model name"));
        };
        let (rest, yield_form) = match rest.strip_suffix(PHOTON_SUFFIX) {
            Some(r) => (r, Some(YieldForm::Photon)),
            None => (rest, None),
        };
        let (rest, domain) = match rest.split_once('@') {
            Some((r, "wavenumber")) => (r, BandDomain::Wavenumber),
            Some((r, "wavelength")) => (r, BandDomain::Wavelength),
            Some(_) => return Err(bad("names an unknown band axis")),
            None => (rest, DEFAULT_DOMAIN),
        };
        let (rest, reflectance) = match rest.split_once('+') {
            Some((r, "rt")) => (r, Some(ReflectanceForm::Tabulated)),
            Some((r, degree)) => {
                let d = degree
                    .strip_prefix('r')
                    .and_then(|d| d.parse::<usize>().ok())
                    .filter(|d| *d <= 20)
                    .ok_or_else(|| bad("has a reflectance part other than +rD (D ≤ 20) or +rt"))?;
                (r, Some(ReflectanceForm::Polynomial(d)))
            }
            None => (rest, None),
        };
        let (components, bands) = rest
            .split_once('x')
            .ok_or_else(|| bad("lacks the KxB part"))?;
        let (absorption, emission) = bands.split_once('/').unwrap_or((bands, bands));
        let count = |s: &str, what: &str| {
            s.parse::<usize>()
                .ok()
                .filter(|n| (1..=6).contains(n))
                .ok_or_else(|| bad(&format!("has {what} \"{s}\"; it must be 1 to 6")))
        };
        Ok(ModelChoice::Fixed(ModelRequest {
            components: count(components, "a component count")?,
            absorption_bands: count(absorption, "an absorption band count")?,
            emission_bands: count(emission, "an emission band count")?,
            reflectance,
            domain,
            yield_form,
        }))
    }
}
