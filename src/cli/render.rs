//! `drape render BAKE_DIR`: preview images of an existing bake, read from its glTF, written to
//! `BAKE_DIR/preview` through a staging folder (a failed render leaves the old preview alone).

use super::args::RenderArgs;
use drape::export::gltf;
use drape::gpu::GpuContext;
use drape::render::{render_sequence, InMemory, RenderOptions};
use drape::Error;

pub fn run(args: RenderArgs) -> anyhow::Result<i32> {
    let dir = &args.bake_dir;
    let report_path = dir.join("report.json");
    let text = std::fs::read_to_string(&report_path)
        .map_err(|e| Error::io(&report_path, "cannot read", e))?;
    let report: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::InvalidField {
            file: report_path.display().to_string(),
            field: "report".into(),
            reason: e.to_string(),
        })?;
    let Some(file) = report["outputs"]["gltf"].as_str() else {
        return Err(Error::InvalidField {
            file: report_path.display().to_string(),
            field: "outputs.gltf".into(),
            reason: "this bake wrote no glTF, which the renderer reads; bake again with the default `--gltf glb` (or bake with `--preview`)".into(),
        }
        .into());
    };
    let (meshes, _fps) = gltf::read(&dir.join(file))?;
    // The glTF's first frame, as the bake's report says (1 for bakes before frame ranges): the
    // shot's first, or the pre-roll's when the bake exported it (numbered before the shot's).
    let frame_start = report
        .get("frame_start")
        .and_then(|f| f.as_u64())
        .map_or(1, |f| f as u32);
    let preroll = &report["preroll"];
    let shown_preroll = (preroll["exported"].as_bool() == Some(true))
        .then(|| preroll["frames"].as_u64())
        .flatten()
        .unwrap_or(0) as u32;
    let first_frame = frame_start.saturating_sub(shown_preroll);
    let staging = dir.join(".preview.partial");
    let _ = std::fs::remove_dir_all(&staging);
    std::fs::create_dir(&staging).map_err(|e| Error::io(&staging, "cannot create", e))?;
    let options = RenderOptions {
        width: args.size.0,
        height: args.size.1,
        wireframe: args.wireframe,
    };
    let result = GpuContext::new(false).and_then(|ctx| {
        render_sequence(ctx, &mut InMemory(&meshes), options, &staging, first_frame)
    });
    let summary = match result {
        Ok(s) => s,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(e.into());
        }
    };
    let preview = dir.join("preview");
    if preview.exists() {
        std::fs::remove_dir_all(&preview).map_err(|e| Error::io(&preview, "cannot replace", e))?;
    }
    std::fs::rename(staging.join("preview"), &preview)
        .map_err(|e| Error::io(&preview, "cannot create", e))?;
    let _ = std::fs::remove_dir_all(&staging);
    println!(
        "rendered {} frames at {}×{} on {}: {:.0} ms per frame into {}",
        summary.frames,
        summary.width,
        summary.height,
        summary.adapter,
        summary.ms_per_frame,
        preview.display()
    );
    Ok(0)
}
