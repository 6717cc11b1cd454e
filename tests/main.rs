//! Every integration test in one binary (`cargo test --release`; one file's tests:
//! `cargo test --release --test integration FILE::`). One binary links the library once
//! instead of once per file, and lets the two test threads take tests from every file.
//! Each file below is one module and one topic; tests/common/ has the shared helpers.

mod common;

mod adjoint;
mod analytic_confocal;
mod auto_window;
mod bdpt_fd;
mod bdpt_forward;
mod bdpt_parameterisation;
mod boundary_opl;
mod boundary_primary;
mod boundary_progress;
mod cli_bad_input;
mod cli_bdpt;
mod cli_checkpoint;
mod cli_exit_codes;
mod cli_json;
mod cli_logging;
mod cli_optimize;
mod cli_output_safety;
mod cli_preview;
mod cli_set_fields;
mod cli_shards;
mod cli_summary;
mod cli_window;
mod closed_containers;
mod derivative_bias;
mod dielectric_pose_fd;
mod diff_parts;
mod embree_crosscheck;
mod energy_and_determinism;
mod far_from_origin;
mod flush_emitter;
mod fuzz_corpus;
mod hard_cases;
mod interior_fd;
mod interior_time_shift;
mod interpenetration;
mod materials_fd;
mod materials_forward;
mod mitsuba_xml;
mod nlos_adjoint;
mod nlos_aim;
mod nlos_boundary_fd;
mod nlos_cli;
mod nlos_fd;
mod nlos_forward;
mod nlos_tracking;
mod opl_precision;
mod optimize_depth;
mod optimize_ior;
mod optimize_pose;
mod ply_mesh;
mod random_scenes;
mod scene_builder;
mod secondary_fd;
mod set_params;
mod shards;
mod sink;
mod small_scenes;
mod sobol_sampler;
mod time_edges;
mod window_cut;
mod window_energy;
