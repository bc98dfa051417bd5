//! dampscope's test suite, one binary (one link instead of one per file): a module per
//! area, named by layer — `sources_*`, `filterbank_*`, `decay_*`/`noise_*`/`schroeder_*`,
//! `report_*` (the report's reference cases), `modal_*`, `diagnose_*`, `sim_*`, `cli_*` and the
//! `*_cli` modules (the binary end to end), and `regression_*`, each named after the bug it
//! caught. `common` holds the shared helpers. Run one area with `cargo test diagnose_`.

mod common;
mod sim_frf_support;

mod atomic_outputs;
mod cli_analyze;
mod cli_bench;
mod cli_demo;
mod cli_streaming;
mod cli_summarize;
mod cli_uff;
mod decay_accuracy;
mod decay_estimator_seam;
mod diagnose_boundary;
mod diagnose_cli;
mod diagnose_damping;
mod diagnose_damping_law;
mod diagnose_elastic_edge;
mod diagnose_evidence;
mod diagnose_kirchhoff;
mod diagnose_kirchhoff_viscoelastic;
mod diagnose_mass;
mod diagnose_mirror;
mod diagnose_noise_floor;
mod diagnose_soft_region;
mod diagnose_two_effects;
mod diagnose_viscoelastic;
mod filterbank_goyder;
mod filterbank_octave;
mod filterbank_sweep;
mod frontend_conformance;
mod maps_cli;
mod modal_acquisition;
mod modal_compare;
mod modal_damped_patch;
mod modal_identify;
mod noise_handling;
mod pyrato_reference;
mod regression_channel_panic_isolated;
mod regression_contradictions;
mod regression_double_hits;
mod regression_empty_bands;
mod regression_foreign_sets;
mod regression_hostile_inputs;
mod regression_ifft_wraparound;
mod regression_measured_records;
mod regression_memory_limits;
mod regression_merged_hits;
mod regression_quantized_recordings;
mod regression_row_order;
mod regression_sparse_hits;
mod regression_two_hits;
mod regression_worse_updates;
mod report_fe_single_mode;
mod report_maps;
mod report_three_sines;
mod resynth_cli;
mod schroeder_oracle;
mod sim_frf;
mod sim_frf_impulse;
mod sim_interface;
mod sim_modes;
mod sim_modes_cli;
mod sim_modes_element;
mod sim_modes_model;
mod sim_simulate;
mod sim_simulate_cli;
mod sim_stream;
mod sources_encoded_blocks;
mod sources_formats;
mod sources_inputs;
mod sources_synth;
mod uff_format;
