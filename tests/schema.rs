//! The extension's JSON Schemas (docs/extensions/AOBAKE_lightmap/schema)
//! against what the baker writes: one page, several pages, the visibility
//! layer at orders 3 and 2 all validate; hand-broken objects are refused
//! with the schema's reason.

mod common;

use aobake::atlas::AtlasSize;
use aobake::job::settings::VisibilityMode;
use boon::{Compiler, SchemaIndex, Schemas};
use serde_json::{Value, json};
use std::path::Path;

struct Contract {
    schemas: Schemas,
    root: SchemaIndex,
    primitive: SchemaIndex,
}

impl Contract {
    fn load() -> Contract {
        let dir =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/extensions/AOBAKE_lightmap/schema");
        let mut schemas = Schemas::new();
        let mut compiler = Compiler::new();
        let mut compile = |name: &str| {
            let text = std::fs::read_to_string(dir.join(name)).expect("schema file");
            let value: Value = serde_json::from_str(&text).expect("schema JSON");
            compiler.add_resource(name, value).expect("resource");
            compiler
                .compile(name, &mut schemas)
                .expect("a valid schema")
        };
        let root = compile("glTF.AOBAKE_lightmap.schema.json");
        let primitive = compile("mesh.primitive.AOBAKE_lightmap.schema.json");
        Contract {
            schemas,
            root,
            primitive,
        }
    }

    /// The schema's reason, if `v` is refused.
    fn check(&self, v: &Value, index: SchemaIndex) -> Option<String> {
        self.schemas
            .validate(v, index)
            .err()
            .map(|e| format!("{e:#}"))
    }

    /// Every AOBAKE_lightmap object of a written GLB validates; returns
    /// the root object and the primitives' objects.
    fn validate_file(&self, glb: &[u8]) -> (Value, Vec<Value>) {
        let (json, _) = common::split(glb);
        let root = json["extensions"]["AOBAKE_lightmap"].clone();
        assert_eq!(self.check(&root, self.root), None, "root {root}");
        let mut prims = Vec::new();
        for m in json["meshes"].as_array().unwrap() {
            for p in m["primitives"].as_array().unwrap() {
                if let Some(e) = p["extensions"].get("AOBAKE_lightmap") {
                    assert_eq!(self.check(e, self.primitive), None, "primitive {e}");
                    prims.push(e.clone());
                }
            }
        }
        assert!(!prims.is_empty());
        (root, prims)
    }
}

fn cornell() -> aobake::gltf::Scene {
    aobake::gltf::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell_box.glb"))
        .unwrap()
}

#[test]
fn every_kind_of_output_validates() {
    let contract = Contract::load();
    let sc = cornell();
    let base = common::settings(64, 8, None);
    // One page, version 1.
    let one = aobake::bake_scene(&sc, &base).unwrap();
    let (root, _) = contract.validate_file(&one.glb);
    assert_eq!(root["version"], 1);
    // Several pages, version 2, with `pages` and each primitive's `page`.
    let pages = aobake::BakeSettings {
        size: AtlasSize::TexelDensity {
            density: 0.2,
            page_size: 128,
        },
        ..base.clone()
    };
    let many = aobake::bake_scene(&sc, &pages).unwrap();
    let (root, prims) = contract.validate_file(&many.glb);
    assert_eq!(root["version"], 2);
    assert!(prims.iter().all(|p| p["page"].is_u64()));
    // The visibility layer at order 3 and at order 2.
    for order in [3, 2] {
        let layer = aobake::BakeSettings {
            visibility: VisibilityMode::All,
            visibility_order: order,
            ..base.clone()
        };
        let out = aobake::bake_scene(&sc, &layer).unwrap();
        let (root, prims) = contract.validate_file(&out.glb);
        assert_eq!(root["visibilityOrder"], order);
        let textures = if order == 3 { 4 } else { 3 };
        assert!(
            prims
                .iter()
                .all(|p| p["visibility"].as_array().unwrap().len() == textures)
        );
    }
}

#[test]
fn broken_objects_are_refused_with_the_schemas_reason() {
    let contract = Contract::load();
    let root = json!({"version": 1, "method": "adaptive", "rays": 256, "seed": 0,
                      "maxDistance": 1.5, "resolution": [64, 64]});
    assert_eq!(contract.check(&root, contract.root), None);
    let refused = |mut v: Value, edit: &dyn Fn(&mut Value), index: SchemaIndex, reason: &str| {
        edit(&mut v);
        let e = contract
            .check(&v, index)
            .unwrap_or_else(|| panic!("{v} was accepted"));
        assert!(e.contains(reason), "{v}: {e}");
    };
    let r = contract.root;
    refused(root.clone(), &|v| v["version"] = json!(2), r, "pages");
    refused(
        root.clone(),
        &|v| v["pages"] = json!([[64, 64]]),
        r,
        "pages",
    );
    refused(
        root.clone(),
        &|v| v["maxDistance"] = json!(0),
        r,
        "maxDistance",
    );
    refused(
        root.clone(),
        &|v| v["resolution"] = json!([64]),
        r,
        "resolution",
    );
    refused(
        root.clone(),
        &|v| v["visibilityOrder"] = json!(4),
        r,
        "visibilityOrder",
    );
    refused(
        root.clone(),
        &|v| {
            v.as_object_mut().unwrap().remove("version");
        },
        r,
        "version",
    );

    let prim = json!({"texCoord": 1, "occlusion": {"index": 0},
                      "sh": [{"index": 1}, {"index": 2}, {"index": 3}],
                      "shScale": vec![1.0; 9], "shOffset": vec![0.0; 9]});
    let p = contract.primitive;
    assert_eq!(contract.check(&prim, p), None);
    refused(
        prim.clone(),
        &|v| v["sh"] = json!([{"index": 1}, {"index": 2}]),
        p,
        "sh",
    );
    refused(
        prim.clone(),
        &|v| v["shScale"] = json!(vec![1.0; 8]),
        p,
        "shScale",
    );
    refused(
        prim.clone(),
        &|v| v["occlusion"] = json!({"texture": 0}),
        p,
        "index",
    );
    refused(prim.clone(), &|v| v["texCoord"] = json!(-1), p, "texCoord");
    refused(
        prim.clone(),
        &|v| {
            v.as_object_mut().unwrap().remove("shOffset");
        },
        p,
        "shOffset",
    );
    // The layer: its three fields together, 16 numbers for 4 textures.
    let four = json!([{"index": 4}, {"index": 5}, {"index": 6}, {"index": 7}]);
    refused(
        prim.clone(),
        &|v| v["visibility"] = four.clone(),
        p,
        "visibilityScale",
    );
    refused(
        prim.clone(),
        &|v| {
            v["visibility"] = four.clone();
            v["visibilityScale"] = json!(vec![1.0; 9]);
            v["visibilityOffset"] = json!(vec![0.0; 9]);
        },
        p,
        "visibilityScale",
    );
}
