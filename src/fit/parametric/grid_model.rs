//! The model's quantities on the grids for one parameter vector ([`GridModel`]): the
//! objective fills them into the buffers of its last evaluation on the same thread.

use super::*;

impl Problem<'_> {
    /// The model's grid quantities at `theta`.
    pub fn grid_model(&self, theta: &[f64]) -> GridModel {
        let mut m = GridModel::default();
        self.fill_grid_model(theta, &mut m);
        m
    }

    /// [`Problem::grid_model`] written into `m`, reusing its storage: every quantity is
    /// written before it is read, so the values do not depend on what `m` held.
    pub(super) fn fill_grid_model(&self, theta: &[f64], m: &mut GridModel) {
        let layout = &self.layout;
        let data = self.data;
        let k_count = layout.spec.components;
        let photon = layout.spec.photon();
        m.kappa.clear();
        m.kappa
            .extend(theta[..k_count].iter().map(|t| t.sin().powi(2)));
        for v in [
            &mut m.absorption_peak,
            &mut m.normaliser,
            &mut m.emission_mean_nm,
            &mut m.shortest_absorbed_nm,
            &mut m.photon_factor,
            &mut m.scale,
        ] {
            v.clear();
        }
        m.peak_index.clear();
        for rows in [
            &mut m.absorption,
            &mut m.emission,
            &mut m.excitation_factor,
            &mut m.cap_factor,
            &mut m.absorption_jacobian,
            &mut m.emission_jacobian,
        ] {
            rows.resize_with(k_count, Vec::new);
        }
        for k in 0..k_count {
            // The unnormalised absorption first, then divided by its peak in place.
            floored_bands_with_jacobian(
                &self.excitation_floor,
                &theta[layout.absorption(k)],
                &self.excitation_u,
                &mut m.bands,
                &mut m.absorption[k],
                &mut m.absorption_jacobian[k],
            );
            let (peak_index, peak) =
                m.absorption[k]
                    .iter()
                    .enumerate()
                    .fold(
                        (0, f64::MIN),
                        |best, (i, &v)| if v > best.1 { (i, v) } else { best },
                    );
            let peak = peak.max(1e-300);
            m.absorption[k].iter_mut().for_each(|v| *v /= peak);
            floored_bands_with_jacobian(
                &self.emission_floor,
                &theta[layout.emission(k)],
                &self.emission_u,
                &mut m.bands,
                &mut m.emission[k],
                &mut m.emission_jacobian[k],
            );
            let (mut normaliser, mut moment) = (0.0, 0.0);
            for ((e, w), l) in m.emission[k]
                .iter()
                .zip(&data.emission_bin_widths)
                .zip(&data.emission_nm)
            {
                normaliser += e * w;
                moment += e * w * l;
            }
            let normaliser = normaliser.max(1e-300);
            let mean = moment / normaliser;
            let shortest = m.absorption[k]
                .iter()
                .position(|&a| a >= ABSORPTION_FLOOR)
                .map(|i| data.excitation_nm[i.saturating_sub(1)])
                .unwrap_or(data.excitation_nm[0]);
            let photon_factor = if photon {
                1.0
            } else {
                (mean / shortest).max(1.0)
            };
            m.scale.push(m.kappa[k] / (photon_factor * normaliser));
            let excitation_factor = &mut m.excitation_factor[k];
            excitation_factor.clear();
            if photon {
                excitation_factor.extend(data.excitation_nm.iter().map(|l| l / mean));
            } else {
                excitation_factor.resize(data.excitation_nm.len(), 1.0);
            }
            m.cap_factor[k].clear();
            m.cap_factor[k].extend(excitation_factor.iter().map(|x| x.max(1.0)));
            m.absorption_peak.push(peak);
            m.peak_index.push(peak_index);
            m.normaliser.push(normaliser);
            m.emission_mean_nm.push(mean);
            m.shortest_absorbed_nm.push(shortest);
            m.photon_factor.push(photon_factor);
        }
        m.reflectance.clear();
        if let ReflectanceForm::Polynomial(_) = layout.spec.reflectance {
            let coefficients = &theta[layout.reflectance()];
            m.reflectance.extend(
                self.reflectance_basis
                    .chunks_exact(coefficients.len().max(1))
                    .map(|basis| {
                        let mut p = 0.0;
                        for (c, pn) in coefficients.iter().zip(basis) {
                            p += c * pn;
                        }
                        sigmoid(p)
                    }),
            );
        }
    }
}
