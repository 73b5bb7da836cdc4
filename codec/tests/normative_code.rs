//! The determinism lint (docs/architecture.md section 3, rule 1): code that decides stream bytes,
//! probability tables, reconstructed attributes or the noise uses integers and IEEE
//! `+ - * / sqrt` only. Platform math functions (`exp`, `ln`, `powf`, `erf`, trigonometry,
//! `mul_add`, ...) may round differently on another machine or library, so they are banned
//! from these files outside their tests. A line may opt out with the comment
//! `platform math allowed:` and the reason, for values that never reach a stream (rate reports).

use std::path::{Path, PathBuf};

/// The normative files, relative to the workspace root: the container, the stream's models
/// and sections, the noise pyramid, the encoder's quantizer (which decides the bytes), and
/// what decides the wrapper's quantization steps: the CPU rasterizer's renders of training
/// views, f's inputs (Plücker embeddings) and f itself, as the encoder evaluates them; and
/// the anchor base's derivation of each view's Gaussians and its context grid; and the
/// importance views and classes (which decide the stream's steps per Gaussian).
const NORMATIVE: [&str; 15] = [
    "bitstream-spec/src",
    "core/src/random.rs",
    "codec/src/stream",
    "codec/src/wrapper/noise.rs",
    "codec/src/wrapper/normal_table.rs",
    "codec/src/wrapper/plucker.rs",
    "codec/src/wrapper/synthesis.rs",
    "render/src/raster",
    "codec/src/portable_math.rs",
    "codec/src/anchor.rs",
    "codec/src/context_grid.rs",
    "encoder/src/compress.rs",
    "encoder/src/importance.rs",
    "encoder/src/anchor/quantize.rs",
    "encoder/src/synthesis.rs",
];

const BANNED: [&str; 22] = [
    "exp", "exp2", "exp_m1", "ln", "ln_1p", "log", "log2", "log10", "powf", "powi", "tanh", "sinh", "cosh", "sin",
    "cos", "tan", "asin", "acos", "atan", "atan2", "hypot", "mul_add",
];

const OPT_OUT: &str = "platform math allowed:";

fn rust_files(path: &Path) -> Vec<PathBuf> {
    if path.is_file() {
        return vec![path.to_path_buf()];
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .collect();
    files.sort();
    files
}

/// The banned calls on one line of code: `.name(` or `name(` as a whole word (so `erf` also
/// catches a free function), skipping comments.
fn banned_calls(line: &str) -> Vec<&'static str> {
    let code = line.split("//").next().unwrap_or("");
    let word_before = |at: usize| code[..at].chars().next_back().is_some_and(|c| c.is_alphanumeric() || c == '_');
    BANNED
        .iter()
        .chain(&["erf", "erfc"])
        .filter(|name| code.match_indices(&format!("{name}(")).any(|(at, _)| !word_before(at)))
        .copied()
        .collect()
}

#[test]
fn normative_code_uses_no_platform_math() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut violations = vec![];
    let mut checked = 0;
    for entry in NORMATIVE {
        for file in rust_files(&root.join(entry)) {
            let text = std::fs::read_to_string(&file).unwrap();
            // Tests may use platform math to check normative values against.
            let code = text.split("#[cfg(test)]").next().unwrap_or("");
            for (i, line) in code.lines().enumerate() {
                let calls = banned_calls(line);
                if !calls.is_empty() && !line.contains(OPT_OUT) {
                    violations.push(format!("{}:{}: {calls:?}: {}", file.display(), i + 1, line.trim()));
                }
            }
            checked += 1;
        }
    }
    assert!(checked >= 24, "only {checked} normative files found: has the layout changed?");
    assert!(violations.is_empty(), "platform math in normative code:\n{}", violations.join("\n"));
}

#[test]
fn the_lint_catches_what_it_bans() {
    assert_eq!(banned_calls("let f = 2f32.powf(x);"), ["powf"]);
    assert_eq!(banned_calls("let y = x.ln() * erf(z);"), ["ln", "erf"]);
    assert_eq!(banned_calls("let y = f64::exp(x);"), ["exp"]);
    assert_eq!(banned_calls("let y = a.mul_add(b, c);"), ["mul_add"]);
    assert!(banned_calls("VoxelOverflow { count } // x.ln() in a comment").is_empty());
    assert!(banned_calls("let v = interp(x); let s = x.sqrt(); let e = p.expected(1);").is_empty());
}
