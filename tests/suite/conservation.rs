//! The conservation block and the yield limit against values worked out by hand: the
//! block every material carries is what `check`'s energy and photon laws report, also
//! where the albedo peaks between samples, and the yield limit is λmin/λ̄e (energy form)
//! or 1 (photon form).

use fluorite::check::{Law, Status, check_material};
use fluorite::material::{Fluorophore, Material, YieldForm};
use fluorite::spectrum::Spectrum;

fn spectrum(wavelength_nm: &[f64], value: &[f64]) -> Spectrum {
    Spectrum::new(wavelength_nm.to_vec(), value.to_vec(), "test").unwrap()
}

/// Every spectrum sampled at 400 and 500 nm only: r falls from 1 to 0.2, a from 1 to 0,
/// e is flat at 0.01/nm (∫e = 1, λ̄e = 450 nm), c = 1 and the yield `y` of `form`. With
/// t = (λ − 400)/100, ρ = t·(1 − 0.8·t) + c·Q(λ)·(1 − t): a parabola whose vertex lies
/// between the samples and off the midpoint.
fn between_samples(form: YieldForm, y: f64) -> Material {
    let grid = [400.0, 500.0];
    Material::new(
        "between-samples",
        spectrum(&grid, &[1.0, 0.2]),
        vec![Fluorophore {
            concentration: 1.0,
            quantum_yield: y,
            yield_form: form,
            concentration_range: None,
            absorption: spectrum(&grid, &[1.0, 0.0]),
            emission: spectrum(&grid, &[0.01, 0.01]),
        }],
    )
}

/// The block a material carries (and writes) against check's energy and photon laws.
fn assert_block_is_check(material: &Material, albedo: f64, photon: f64) {
    let report = check_material(material);
    assert!(report.valid, "{}", report.to_json());
    let energy = report.law(Law::Energy);
    let photons = report.law(Law::Photons);
    let block = material
        .conservation
        .expect("Material::new computes the block");
    let written: Material = serde_json::from_str(&material.to_json()).unwrap();
    for c in [block, written.conservation.unwrap()] {
        assert!((c.max_energy_albedo - albedo).abs() < 1e-12, "{c:?}");
        assert!((c.max_photon_ratio - photon).abs() < 1e-12, "{c:?}");
        assert_eq!(c.max_energy_albedo, energy.worst_value);
        assert_eq!(c.max_photon_ratio, photons.worst_value);
    }
}

#[test]
fn energy_form_block_finds_the_vertex_between_samples() {
    // ρ(t) = 0.1 + 0.9·t − 0.8·t²: vertex at t = 0.9/1.6 = 0.5625 (456.25 nm), where
    // ρ = 0.1 + 0.9²/3.2 = 0.353125; the midpoint gives only 0.35, the samples 0.1 and
    // 0.2. Photons: Q·λ̄e/λmin = 0.1·450/400 = 0.1125.
    let m = between_samples(YieldForm::Energy, 0.1);
    assert_block_is_check(&m, 0.353125, 0.1125);
    let energy = check_material(&m).law(Law::Energy).clone();
    assert!(
        (energy.worst_nm.unwrap() - 456.25).abs() < 1e-9,
        "{energy:?}"
    );
}

#[test]
fn photon_form_block_finds_the_vertex_between_samples() {
    // Q(λ) = Φ·λ/λ̄e = 0.1·(400 + 100·t)/450, so c·Q·a = (400 − 300·t − 100·t²)/4500 and
    // ρ = 4/45 + (14/15)·t − (37/45)·t², maximal at t = 21/37 with
    // ρ = 4/45 + (14/15)²/(4·37/45). Photons: Φ = 0.1.
    let m = between_samples(YieldForm::Photon, 0.1);
    let top = 4.0 / 45.0 + (14.0f64 / 15.0).powi(2) / (4.0 * 37.0 / 45.0);
    assert_block_is_check(&m, top, 0.1);
    let energy = check_material(&m).law(Law::Energy).clone();
    let vertex_nm = 400.0 + 100.0 * 21.0 / 37.0;
    assert!(
        (energy.worst_nm.unwrap() - vertex_nm).abs() < 1e-9,
        "{energy:?}"
    );
}

#[test]
fn a_material_without_fluorophores_has_zero_photon_ratio() {
    // ρ = r, largest at its larger sample; no fluorophore, no photon bound (0).
    let m = Material::new("plain", spectrum(&[400.0, 500.0], &[0.3, 0.7]), vec![]);
    let c = m.conservation.unwrap();
    assert_eq!(c.max_energy_albedo, 0.7);
    assert_eq!(c.max_photon_ratio, 0.0);
}

/// a = 0, 0.5, 1, 0 at 350–380 nm (so absorption starts just after the zero sample at
/// 350 nm: λmin = 350) and a flat emission on 400–500 nm (λ̄e = 450 nm).
fn uv_absorber(form: YieldForm, y: f64) -> Fluorophore {
    Fluorophore {
        concentration: 0.5,
        quantum_yield: y,
        yield_form: form,
        concentration_range: None,
        absorption: spectrum(&[350.0, 360.0, 370.0, 380.0], &[0.0, 0.5, 1.0, 0.0]),
        emission: spectrum(&[400.0, 500.0], &[0.01, 0.01]),
    }
}

#[test]
fn yield_limit_is_shortest_absorbed_over_mean_emission() {
    // Energy form: Q ≤ λmin/λ̄e = 350/450 = 7/9.
    assert!((uv_absorber(YieldForm::Energy, 0.5).yield_limit() - 7.0 / 9.0).abs() < 1e-15);
    // Photon form: Φ ≤ 1 whatever the spectra.
    assert_eq!(uv_absorber(YieldForm::Photon, 0.5).yield_limit(), 1.0);
    // Absorbing only above the mean emission (λmin = 500 > 450 nm): the range law's 1.
    let mut red = uv_absorber(YieldForm::Energy, 0.5);
    red.absorption = spectrum(&[500.0, 510.0], &[1.0, 0.0]);
    assert_eq!(red.yield_limit(), 1.0);
    // Nothing absorbed: nothing bounds Q but the range law.
    let mut none = uv_absorber(YieldForm::Energy, 0.5);
    none.absorption = spectrum(&[350.0, 360.0], &[0.0, 0.0]);
    assert_eq!(none.yield_limit(), 1.0);
}

#[test]
fn the_photon_law_breaks_just_past_the_yield_limit() {
    let r = spectrum(&[300.0, 800.0], &[0.5, 0.5]);
    let limit = 7.0 / 9.0;
    let at = Material::new("at", r.clone(), vec![uv_absorber(YieldForm::Energy, limit)]);
    let report = check_material(&at);
    assert_eq!(report.law(Law::Photons).status, Status::Pass);
    assert!((at.conservation.unwrap().max_photon_ratio - 1.0).abs() < 1e-12);

    let past = Material::new(
        "past",
        r,
        vec![uv_absorber(YieldForm::Energy, limit * (1.0 + 1e-6))],
    );
    let photons = check_material(&past).law(Law::Photons).clone();
    assert_eq!(photons.status, Status::Fail);
    assert_eq!(photons.worst_nm, Some(350.0));
    assert!(
        photons.violations[0].contains("allows Q ≤ 0.777778"),
        "{:?}",
        photons.violations
    );
}
