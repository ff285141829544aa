//! Schema check (tests only): every written file's `AOBAKE_lightmap`
//! objects against the extension's JSON Schemas.
//!
//! In: the output document's JSON, just before it is serialized. Out:
//! nothing, or a panic naming the object and the schema's reason. Built
//! with the `contract-check` feature, which the crate's own
//! dev-dependency on itself turns on: so every file that `cargo test`
//! writes, through the library or the command line, is validated
//! (`docs/extensions/AOBAKE_lightmap/schema`), and release builds carry
//! neither the check nor its dependency.

use boon::{Compiler, SchemaIndex, Schemas};
use serde_json::Value;
use std::sync::OnceLock;

const ROOT: &str =
    include_str!("../../docs/extensions/AOBAKE_lightmap/schema/glTF.AOBAKE_lightmap.schema.json");
const PRIMITIVE: &str = include_str!(
    "../../docs/extensions/AOBAKE_lightmap/schema/mesh.primitive.AOBAKE_lightmap.schema.json"
);

struct Compiled {
    schemas: Schemas,
    root: SchemaIndex,
    primitive: SchemaIndex,
}

fn compiled() -> &'static Compiled {
    static C: OnceLock<Compiled> = OnceLock::new();
    C.get_or_init(|| {
        let mut schemas = Schemas::new();
        let mut compiler = Compiler::new();
        let mut compile = |name: &str, text: &str| {
            let value: Value = serde_json::from_str(text).expect("schema JSON");
            compiler.add_resource(name, value).expect("schema resource");
            compiler
                .compile(name, &mut schemas)
                .expect("a valid schema")
        };
        let root = compile("glTF.AOBAKE_lightmap.schema.json", ROOT);
        let primitive = compile("mesh.primitive.AOBAKE_lightmap.schema.json", PRIMITIVE);
        Compiled {
            schemas,
            root,
            primitive,
        }
    })
}

/// Panics unless the root's and every primitive's `AOBAKE_lightmap`
/// object validates.
pub(crate) fn assert_valid(json: &Value) {
    let c = compiled();
    let check = |v: &Value, index: SchemaIndex, what: &str| {
        // serde_json's arbitrary_precision numbers are re-read as plain ones.
        let plain: Value = serde_json::from_str(&v.to_string()).expect("json");
        if let Err(e) = c.schemas.validate(&plain, index) {
            panic!("{what}.extensions.AOBAKE_lightmap breaks the schema: {e:#}");
        }
    };
    if let Some(root) = json.pointer("/extensions/AOBAKE_lightmap") {
        check(root, c.root, "the root");
    }
    for (mi, m) in super::accessor::array(json, "meshes").iter().enumerate() {
        for (pi, p) in super::accessor::array(m, "primitives").iter().enumerate() {
            if let Some(e) = p.pointer("/extensions/AOBAKE_lightmap") {
                check(e, c.primitive, &super::accessor::primitive_label(mi, pi));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::assert_valid;
    use serde_json::json;

    fn primitive(ext: serde_json::Value) -> serde_json::Value {
        json!({"meshes": [{"primitives": [{"attributes": {}, "extensions": {"AOBAKE_lightmap": ext}}]}]})
    }

    fn good() -> serde_json::Value {
        json!({
            "texCoord": 1,
            "occlusion": {"index": 0},
            "sh": [{"index": 1}, {"index": 2}, {"index": 3}],
            "shScale": [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
            "shOffset": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        })
    }

    #[test]
    fn a_written_primitive_object_passes() {
        assert_valid(&primitive(good()));
    }

    #[test]
    #[should_panic(
        expected = "meshes[0].primitives[0].extensions.AOBAKE_lightmap breaks the schema"
    )]
    fn a_broken_primitive_object_stops_the_write() {
        let mut ext = good();
        ext["sh"] = json!([{"index": 1}]);
        assert_valid(&primitive(ext));
    }
}
