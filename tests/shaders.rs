//! Every WGSL kernel parses and validates with naga (the compiler wgpu uses), each listed entry
//! point exists, and every struct of `shaders/common.wgsl` has the size of its Rust mirror in
//! `src/gpu/layout.rs`, so buffers upload unchanged.

use drape::gpu::kernels::{source, KERNEL_FILES};
use drape::gpu::layout::MIRRORS;

fn module(file: &str) -> (naga::Module, String) {
    let text = source(file);
    let module = naga::front::wgsl::parse_str(&text)
        .unwrap_or_else(|e| panic!("{file}:\n{}", e.emit_to_string(&text)));
    (module, text)
}

#[test]
fn every_kernel_validates_and_has_its_entry_points() {
    for (file, _, entries) in KERNEL_FILES {
        let (module, _) = module(file);
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{file}: {e:?}"));
        for entry in entries {
            assert!(
                module.entry_points.iter().any(|e| e.name == *entry),
                "{file}: no entry point {entry}"
            );
        }
    }
}

#[test]
fn wgsl_structs_match_their_rust_mirrors() {
    let (module, _) = module("predict.wgsl");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    for (name, rust_size) in MIRRORS {
        let (handle, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("common.wgsl has no struct {name}"));
        assert_eq!(
            layouter[handle].size as usize, rust_size,
            "struct {name}: WGSL and Rust sizes differ"
        );
    }
}
