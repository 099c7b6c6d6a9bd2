//! The fit on variants of the synthetic presets that stand for materials not in
//! `../shared`: crosstalk as strong as POLGREE's and TEXTYELL's, a pigment at the
//! conservation limit, a small Stokes shift (optical brighteners), a weak UV absorption
//! tail (which caps the constant-Q form's yield for every row), and a photon-form truth.
//! The colour is judged against the matrix as generated (every cell, as `fit` reports it;
//! `tests/colour_reference.rs` checks that report apart from the code), or, for the
//! default fit of a variant with 4 % crosstalk, against the same draw generated without
//! that crosstalk.

use fluorite::YieldForm;
use fluorite::evaluate::stability::material_delta_e;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::synth::{Band, SynthSpec};

fn variants() -> Vec<(String, SynthSpec)> {
    let mut out = Vec::new();
    for preset in ["green-dye", "red-pigment", "brightener"] {
        let base = SynthSpec::preset(preset).unwrap();
        out.push((preset.to_string(), base.clone()));
        let mut s = base.clone();
        s.crosstalk = 0.04;
        out.push((format!("{preset}, crosstalk 4 %"), s));
        let mut s = base.clone();
        s.concentration = 1.0;
        s.yield_fraction_of_limit = 1.0;
        out.push((format!("{preset} at the conservation limit"), s));
        let mut s = base.clone();
        let shift = s.absorption[0].centre_nm + 25.0 - s.emission[0].centre_nm;
        s.emission.iter_mut().for_each(|b| b.centre_nm += shift);
        out.push((format!("{preset}, Stokes shift 25 nm"), s));
        let mut s = base.clone();
        s.absorption.push(Band {
            centre_nm: 310.0,
            width_nm: 15.0,
            weight: 0.15,
        });
        out.push((format!("{preset} with a UV tail"), s));
        let mut s = base;
        s.yield_form = YieldForm::Photon;
        s.concentration = 0.9;
        s.yield_fraction_of_limit = 0.95;
        out.push((format!("{preset}, photon-form truth"), s));
    }
    out
}

fn material(outcome: FitOutcome) -> fluorite::Material {
    match outcome {
        FitOutcome::Material(m) => *m,
        FitOutcome::Shapes(_) => panic!("expected a material"),
    }
}

/// The search meets ΔE2000 ≤ 1 under all four lights with one fluorophore (each variant
/// has one) and every law holding; the default fit keeps one fluorophore (bar the red
/// pigment's photon-form truth, which no one-component model reaches: two, nearer the
/// truth than the grid fit) and meets it
/// under d65, a and f11, against the matrix as generated or, for the variants with 4 %
/// crosstalk next to the diagonal, against the same draw generated without it (the
/// instrument's offset, chosen by the variant, not by what the fit says; the red pigment's grid fit is 1.10 from the first
/// under f11, 0.77 from the second and 0.22 from the truth (0.33 at most, under A), where
/// the two fluorophores it escalated to were up to 1.30 from it, under uv).
#[test]
fn one_fluorophore_variants_meet_the_bound() {
    for (label, spec) in variants() {
        let (m, truth) = spec.generate().unwrap();
        let grid = material(fit(&m, &FitOptions::default()).unwrap());
        grid.validate().unwrap();
        let report = grid.fit.as_ref().unwrap();
        let reason = &report.escalation.as_ref().unwrap().reason;
        if label == "red-pigment, photon-form truth" && grid.fluorophores.len() == 2 {
            // No one-component model of either axis reaches this matrix (a pigment at
            // 0.95 of its photon-form limit, c 0.9: gaussian:1x2/1+rt@wavelength/photon,
            // its truth's structure, ends at BIC 9,558 with Φ on its bound, the grid model
            // at 2,945); two photon-form components on wavelength reach 2,385, and the
            // default fit's lower-BIC rule takes them. Nearer the truth than the grid fit.
            assert!(
                reason.contains("of lower BIC than the grid model"),
                "{reason}"
            );
            let tabulated = crate::common::grid_fit(&m);
            let lights = fluorite::colour::Light::standard();
            let (kept, gridded) = (
                material_delta_e(&grid, &truth, &lights),
                material_delta_e(&tabulated, &truth, &lights),
            );
            assert!(
                kept < gridded,
                "{label}: {kept:.3} against the grid fit's {gridded:.3}"
            );
        } else {
            assert_eq!(grid.fluorophores.len(), 1, "{label}: {}", report.model);
        }
        let reference = if spec.crosstalk >= 0.01 {
            let mut without = spec.clone();
            without.crosstalk = 0.0;
            without.generate().unwrap().0
        } else {
            m.clone()
        };
        for (light, de) in crate::common::delta_e_to_matrix(&grid, &reference, &["d65", "a", "f11"])
        {
            assert!(
                de <= 1.0,
                "{label}: default fit under {light}: {de:.3} ({reason})"
            );
        }
        let options = FitOptions {
            model: ModelChoice::Auto,
            max_delta_e: Some(1.0),
            ..FitOptions::default()
        };
        let searched = material(fit(&m, &options).unwrap());
        searched.validate().unwrap();
        let report = searched.fit.as_ref().unwrap();
        println!("{label}: {} {:?}", report.model, report.delta_e2000);
        assert!(report.model_search.as_ref().unwrap().met, "{label}");
        assert!(
            report.delta_e2000.values().all(|&v| v <= 1.0),
            "{label}: {:?}",
            report.delta_e2000
        );
        assert_eq!(searched.fluorophores.len(), 1, "{label}: {}", report.model);
    }
}
