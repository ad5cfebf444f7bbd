//! `antumbra`: the command-line tool of the Antumbra library.
//!
//! Renders demo pictures from built-in data, renders and bakes ambient occlusion
//! of user meshes, lights them with HDR environment maps, and benchmarks and
//! cross-checks the core's ray casters. File formats (OBJ, glTF, OpenEXR,
//! PNG) are handled here, never in the core. Run `antumbra --help` for the
//! commands.

mod bounds;
mod builtin;
mod camera;
mod cli;
mod commands;
mod envmap;
mod error;
mod gltf_mesh;
mod ground;
mod hemi_shading;
mod lightmap;
mod mesh;
mod picture;
mod progress;
mod prt;
mod raster;
mod ray_batch;
mod render;
mod sampling;
mod scene;
mod shard;
mod tonemap;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match commands::run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", error.chain());
            ExitCode::FAILURE
        }
    }
}
