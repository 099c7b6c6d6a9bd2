//! Least-squares fits of forms to sampled spectra.
