//! `propsalive inspect MODEL`.

use std::path::PathBuf;

use anyhow::Result;
use pa_model::describe::describe;
use pa_model::Model;

#[derive(clap::Args)]
pub struct Args {
    /// The glTF 2.0 model (.glb or .gltf).
    pub model: PathBuf,
}

pub fn run(args: Args) -> Result<()> {
    let model = Model::load(&args.model)?;
    out!("{}", describe(&model));
    Ok(())
}
