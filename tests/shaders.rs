//! Every WGSL kernel and the preview shader parse and validate with naga (the compiler wgpu
//! uses) and have their entry points; every struct of `shaders/common.wgsl` has the size and the
//! member offsets of its Rust mirror in `src/gpu/layout.rs`, so buffers upload unchanged; and
//! every constant the kernels share with the Rust code (list lengths, flags, collider kinds) has
//! the Rust value.

use drape::gpu::kernels::{source, KERNEL_FILES};
use drape::gpu::layout::MIRRORS;

fn module(file: &str) -> (naga::Module, String) {
    let text = source(file);
    let module = naga::front::wgsl::parse_str(&text)
        .unwrap_or_else(|e| panic!("{file}:\n{}", e.emit_to_string(&text)));
    (module, text)
}

/// `module` (named `file`) validates and has every entry point of `entries`.
fn assert_valid_with_entries(file: &str, module: &naga::Module, entries: &[&str]) {
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(module)
    .unwrap_or_else(|e| panic!("{file}: {e:?}"));
    for entry in entries {
        assert!(
            module.entry_points.iter().any(|e| e.name == *entry),
            "{file}: no entry point {entry}"
        );
    }
}

/// Every struct of `mirrors` is in `module` with the size of its Rust mirror.
fn assert_sizes(file: &str, module: &naga::Module, mirrors: &[(&str, usize)]) {
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    for (name, rust_size) in mirrors {
        let (handle, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(*name))
            .unwrap_or_else(|| panic!("{file} has no struct {name}"));
        assert_eq!(
            layouter[handle].size as usize, *rust_size,
            "struct {name}: WGSL and Rust sizes differ"
        );
    }
}

#[test]
fn every_kernel_validates_and_has_its_entry_points() {
    for (file, _, entries) in KERNEL_FILES {
        let (module, _) = module(file);
        assert_valid_with_entries(file, &module, entries);
    }
}

#[test]
fn wgsl_structs_match_their_rust_mirrors() {
    let (common, _) = module("predict.wgsl");
    assert_sizes("common.wgsl", &common, &MIRRORS);
    let (forces, _) = module("forces.wgsl");
    assert_sizes("forces.wgsl", &forces, &drape::gpu::layout::FIELD_MIRRORS);
}

#[test]
fn constants_shared_with_rust_have_its_values() {
    use drape::gpu::layout::SHARED_CONSTANTS;
    let mut found = vec![0; SHARED_CONSTANTS.len()];
    for (file, _, _) in KERNEL_FILES {
        let (module, _) = module(file);
        for (_, constant) in module.constants.iter() {
            let Some(name) = constant.name.as_deref() else {
                continue;
            };
            let Some(k) = SHARED_CONSTANTS.iter().position(|(n, _)| *n == name) else {
                continue;
            };
            let value = match module.global_expressions[constant.init] {
                naga::Expression::Literal(literal) => match literal {
                    naga::Literal::U32(v) => v as f64,
                    naga::Literal::I32(v) => v as f64,
                    naga::Literal::F32(v) => v as f64,
                    other => panic!("{file}: {name} is {other:?}"),
                },
                ref other => panic!("{file}: {name} is not a literal: {other:?}"),
            };
            assert_eq!(
                value, SHARED_CONSTANTS[k].1,
                "{file}: {name} = {value}, Rust says {}",
                SHARED_CONSTANTS[k].1
            );
            found[k] += 1;
        }
    }
    for ((name, _), count) in SHARED_CONSTANTS.iter().zip(&found) {
        assert!(*count > 0, "no kernel declares {name}");
    }
}

#[test]
fn wgsl_members_sit_where_their_rust_mirrors_put_them() {
    use drape::gpu::layout::MIRROR_OFFSETS;
    let (module, _) = module("predict.wgsl");
    for (name, fields) in MIRROR_OFFSETS {
        let ty = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("common.wgsl has no struct {name}"))
            .1;
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!("{name} is not a struct");
        };
        let wgsl: Vec<(&str, usize)> = members
            .iter()
            .map(|m| (m.name.as_deref().unwrap_or("?"), m.offset as usize))
            .collect();
        assert_eq!(
            wgsl,
            fields.to_vec(),
            "struct {name}: WGSL members and offsets differ from the Rust mirror's"
        );
    }
}

#[test]
fn the_preview_shader_validates_and_has_its_entry_points() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/shaders/render.wgsl");
    let text = std::fs::read_to_string(path).unwrap();
    let module = naga::front::wgsl::parse_str(&text)
        .unwrap_or_else(|e| panic!("render.wgsl:\n{}", e.emit_to_string(&text)));
    let entries = ["vs_main", "fs_main", "vs_line", "fs_line", "vs_shadow"];
    assert_valid_with_entries("render.wgsl", &module, &entries);
}

#[test]
fn bind_groups_bind_every_buffer_where_the_shaders_declare_it() {
    use drape::gpu::buffers::BINDINGS;
    let mut seen = 0;
    for (file, _, _) in KERNEL_FILES {
        let (module, _) = module(file);
        for (_, var) in module.global_variables.iter() {
            let Some(b) = &var.binding else { continue };
            let name = var.name.as_deref().unwrap_or("");
            let expected = BINDINGS
                .get(b.group as usize)
                .and_then(|g| g.get(b.binding as usize));
            assert_eq!(
                expected,
                Some(&name),
                "{file}: @group({}) @binding({}) is {name}, src/gpu/buffers.rs binds {expected:?} there",
                b.group,
                b.binding
            );
            seen += 1;
        }
    }
    let total: usize = BINDINGS.iter().map(|g| g.len()).sum();
    assert!(seen >= total, "every binding declared somewhere");
}

#[test]
fn the_skin_kernels_validate_and_match_their_rust_mirrors() {
    use drape::gpu::skin::{BINDINGS, ENTRIES, MIRRORS, SOURCE};
    let module = naga::front::wgsl::parse_str(SOURCE)
        .unwrap_or_else(|e| panic!("skin.wgsl:\n{}", e.emit_to_string(SOURCE)));
    assert_valid_with_entries("skin.wgsl", &module, &ENTRIES);
    assert_sizes("skin.wgsl", &module, &MIRRORS);
    let mut bound: Vec<(u32, &str)> = module
        .global_variables
        .iter()
        .filter_map(|(_, v)| Some((v.binding.as_ref()?.binding, v.name.as_deref()?)))
        .collect();
    bound.sort();
    let names: Vec<&str> = bound.iter().map(|(_, n)| *n).collect();
    assert_eq!(names, BINDINGS, "skin.wgsl's bindings in order");
    assert!(bound.iter().enumerate().all(|(i, (b, _))| *b == i as u32));
}

#[test]
fn the_keyframe_kernel_validates_and_matches_its_rust_mirrors() {
    use drape::gpu::drive::{source, BINDINGS, ENTRY, GROUP_INDEX, MIRRORS};
    let text = source();
    let module = naga::front::wgsl::parse_str(&text)
        .unwrap_or_else(|e| panic!("drive.wgsl:\n{}", e.emit_to_string(&text)));
    assert_valid_with_entries("drive.wgsl", &module, &[ENTRY]);
    assert_sizes("drive.wgsl", &module, &MIRRORS);
    let mut bound: Vec<(u32, &str)> = module
        .global_variables
        .iter()
        .filter_map(|(_, v)| {
            let b = v.binding.as_ref()?;
            (b.group == GROUP_INDEX).then_some((b.binding, v.name.as_deref()?))
        })
        .collect();
    bound.sort();
    let names: Vec<&str> = bound.iter().map(|(_, n)| *n).collect();
    assert_eq!(names, BINDINGS, "drive.wgsl's group-3 bindings in order");
    assert!(bound.iter().enumerate().all(|(i, (b, _))| *b == i as u32));
}
