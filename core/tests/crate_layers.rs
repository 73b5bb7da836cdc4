//! The workspace's layering (docs/architecture.md section 5): every crate depends only on
//! crates of lower layers, so that an arrow never runs back up (the dataset loader does not
//! reach into the codec, the codec does not render), and only the programs under `apps/`
//! depend on the command-line crate. Read from each member's `Cargo.toml`.

use std::path::Path;

/// Each member crate's folder, its package name and its layer: 0 holds no pwgs dependency,
/// and a crate may depend on crates of lower layers only.
const LAYERS: [(&str, &str, u32); 16] = [
    ("bitstream-spec", "pwgs-bitstream", 0),
    ("core", "pwgs-core", 0),
    ("rd-report", "pwgs-rd-report", 0),
    ("rating", "pwgs-rating", 0),
    ("apps/cli", "pwgs-cli", 0),
    ("codec", "pwgs-codec", 1),
    ("dataset", "pwgs-dataset", 1),
    ("render", "pwgs-render", 2),
    ("encoder", "pwgs-encoder", 3),
    ("conformance", "pwgs-conformance", 3),
    ("player", "pwgs-player", 3),
    ("apps/pwdec", "pwgs-pwdec", 4),
    ("apps/pwenc", "pwgs-pwenc", 4),
    ("apps/pwplay", "pwgs-pwplay", 4),
    ("apps/pwbench", "pwgs-pwbench", 4),
    ("apps/pwrate", "pwgs-pwrate", 4),
];

/// The pwgs crates a manifest names in its `[dependencies]` (not its dev-dependencies: tests
/// may use what sits above).
fn pwgs_dependencies(manifest: &str) -> Vec<String> {
    let mut section = "";
    let mut names = Vec::new();
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            section = line;
        } else if section == "[dependencies]" && line.starts_with("pwgs-") {
            let name = line.split(|c: char| c == '.' || c == '=' || c.is_whitespace()).next().unwrap_or("");
            names.push(name.to_string());
        }
    }
    names
}

#[test]
fn every_crate_depends_only_on_lower_layers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("core/ lies in the workspace");
    let workspace = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let layer_of = |name: &str| LAYERS.iter().find(|(_, n, _)| *n == name).map(|&(_, _, l)| l);
    for (dir, name, layer) in LAYERS {
        assert!(workspace.contains(&format!("\"{dir}\"")), "{dir} is not a workspace member");
        let manifest = std::fs::read_to_string(root.join(dir).join("Cargo.toml")).unwrap();
        assert!(manifest.contains(&format!("name = \"{name}\"")), "{dir}/Cargo.toml is not {name}");
        for dependency in pwgs_dependencies(&manifest) {
            let below = layer_of(&dependency).unwrap_or_else(|| panic!("{name} depends on {dependency}, in no layer"));
            assert!(below < layer, "{name} (layer {layer}) depends on {dependency} (layer {below})");
            let program = dir.starts_with("apps/") && dir != "apps/cli";
            assert!(dependency != "pwgs-cli" || program, "{name} is no program under apps/ but depends on pwgs-cli");
        }
    }
    let members = workspace.split("members = [").nth(1).and_then(|m| m.split(']').next()).unwrap();
    assert_eq!(members.matches('"').count() / 2, LAYERS.len(), "a workspace member has no layer: {members}");
}

#[test]
fn dependencies_are_read_from_the_dependencies_section_only() {
    let manifest = "[package]\nname = \"x\"\n[dependencies]\npwgs-core.workspace = true\npwgs-codec = { workspace = true }\nglam.workspace = true\n[dev-dependencies]\npwgs-render.workspace = true\n";
    assert_eq!(pwgs_dependencies(manifest), ["pwgs-core", "pwgs-codec"]);
}
