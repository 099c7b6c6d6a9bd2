//! Crosstalk next to the diagonal (`fit::crosstalk`): what the fit finds and removes,
//! asserted against the synthetic truth (the fraction the matrix was written with, the
//! true reflectance), never against the code's own output.

use fluorite::Material;
use fluorite::fit::{FitOptions, FitOutcome, fit};
use fluorite::measurement::Measurement;
use fluorite::synth::SynthSpec;

/// A dye-free spec (the `plain` preset) at noise `sigma`, without the synthesiser's
/// crosstalk.
fn plain_spec(sigma: f64) -> SynthSpec {
    let mut spec = SynthSpec::preset("plain").unwrap();
    spec.noise_sigma = sigma;
    spec.crosstalk = 0.0;
    spec
}

/// `m` with a bandpass wider than the step: `fraction` of the true reflectance `truth`
/// moved from each diagonal cell into each of its measured emission neighbours (j ± 1),
/// so each row keeps its energy and the diagonal alone reads low.
fn spread_to_neighbours(m: &mut Measurement, truth: &Material, fraction: f64) {
    for (i, j, below, above) in m.diagonal_neighbours() {
        let r = truth.diagonal(m.excitation_nm[i]);
        for c in [below, above].into_iter().flatten() {
            if m.get(i, c).is_finite() {
                *m.get_mut(i, c) += fraction * r;
                *m.get_mut(i, j) -= fraction * r;
            }
        }
    }
}

/// The fitted material of `m` by the default fit.
fn fitted(m: &Measurement) -> Material {
    match fit(m, &FitOptions::default()).unwrap() {
        FitOutcome::Material(material) => *material,
        FitOutcome::Shapes(_) => panic!("{}: a material", m.name),
    }
}

/// A dye-free matrix is fitted as a plain reflector to the cells less their crosstalk:
/// its report says so (it was left out before), and its reflectance is the truth's, the
/// crosstalk's net energy given back (a bandpass wider than the step takes 2 × 3 % of the
/// reflectance out of the diagonal; the reflectance without it would be that much low).
#[test]
fn a_plain_reflector_reports_the_crosstalk_and_gets_its_energy_back() {
    let sigma = 6e-4;
    let fraction = 0.03;
    for seed in 1..4 {
        let mut spec = plain_spec(sigma);
        spec.seed = seed;
        let (mut m, truth) = spec.generate().unwrap();
        spread_to_neighbours(&mut m, &truth, fraction);
        let material = fitted(&m);
        assert!(
            material.fluorophores.is_empty(),
            "seed {seed}: a plain reflector"
        );
        let report = material.fit.as_ref().unwrap();
        let found = report
            .crosstalk
            .as_ref()
            .unwrap_or_else(|| panic!("seed {seed}: crosstalk reported"));
        assert!(found.removed, "{found:?}");
        // Fractions of the measured diagonal, (1 − 2f)·r away from the grid's ends.
        let want = fraction / (1.0 - 2.0 * fraction);
        for (got, error) in [
            (found.below, found.below_error),
            (found.above, found.above_error),
        ] {
            assert!(
                (got - want).abs() <= 4.0 * error + 0.02 * fraction,
                "seed {seed}: {got} against {want} (± {error})"
            );
        }
        assert_reflectance_is_the_truths(&material, &truth, sigma, found);
    }
}

/// Every reflectance sample of `material` within 4 σ plus 4 × the crosstalk's errors
/// (times the reflectance) of the truth's.
fn assert_reflectance_is_the_truths(
    material: &Material,
    truth: &Material,
    sigma: f64,
    found: &fluorite::material::CrosstalkCorrection,
) {
    let error = found.below_error + found.above_error;
    for (&nm, &r) in material
        .reflectance
        .wavelength_nm
        .iter()
        .zip(&material.reflectance.value)
    {
        let want = truth.diagonal(nm);
        assert!(
            (r - want).abs() <= 4.0 * sigma + 4.0 * error * want,
            "{} at {nm} nm: {r} against {want}",
            material.name
        );
    }
}

/// A material file whose `crosstalk` block gives only the fractions (written by hand, or by
/// a version before the others) loads: the rest take their defaults, the cells count as
/// measured (`removed` false).
#[test]
fn a_crosstalk_block_with_only_the_fractions_loads() {
    let mut spec = SynthSpec::preset("red-pigment").unwrap();
    spec.crosstalk = 0.03;
    let (m, _) = spec.generate().unwrap();
    let material = fitted(&m);
    let mut json: serde_json::Value = serde_json::from_str(&material.to_json()).unwrap();
    json["fit"]["crosstalk"] = serde_json::json!({"below": 0.04, "above": -0.03});
    let path = std::path::Path::new("partial-crosstalk.json");
    let loaded = Material::from_json(&json.to_string(), path).unwrap();
    let found = loaded.fit.unwrap().crosstalk.unwrap();
    assert_eq!((found.below, found.above), (0.04, -0.03));
    assert_eq!(
        (found.below_error, found.above_error, found.quiet_rows),
        (0.0, 0.0, 0)
    );
    assert!(!found.removed && found.note.is_empty() && found.delta_e2000.is_empty());
}
