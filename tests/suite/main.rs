//! The integration tests, as one test binary (one link for `cargo test`): one module per
//! topic. `common` holds the fixtures they share; tests that need `../shared/data` print
//! SKIPPED with the reason when it is absent, and fail under CI (`CI=true`), which has it.

mod common;

mod architecture;
mod band_axis;
mod band_floor;
mod bands_options;
mod check;
mod class;
mod cli_fit;
mod cli_usage;
mod colour_noise;
mod colour_reference;
mod committed_fits;
mod conservation;
mod crosstalk;
mod default_fit;
mod doc_examples;
mod eem_instrument;
mod eem_joint;
mod eem_options;
mod eem_scatter_leak;
mod eem_second_order;
mod export;
mod export_exr_rgb;
mod export_options;
mod export_renderers;
mod fit_class;
mod fit_measured;
mod fit_series;
mod fit_synthetic;
mod formats;
mod formats_lab;
mod fuzz;
mod image_diff;
mod image_fit;
mod image_per_pixel;
mod image_robust;
mod image_synth;
mod import;
mod limits;
mod model_search;
mod noise_aware_search;
mod parametric;
mod plot;
mod plot_masked;
mod render;
mod render_compare;
mod render_map;
mod reproducible_outputs;
mod special_outputs;
mod stability;
mod synth_components;
mod units_percent;
mod uv_tail;
