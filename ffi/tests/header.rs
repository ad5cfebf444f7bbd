//! Generates `include/antumbra.h` with the pinned cbindgen and compares it with the
//! committed header: a stale header fails with a diff; `ANTUMBRA_BLESS=1` rewrites it.

use std::path::{Path, PathBuf};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Macros the header needs that cbindgen cannot derive from Rust items: the version
/// (from the crate version, never typed by hand) and the nodiscard attribute.
fn after_includes() -> String {
    let (major, minor, patch) = (
        env!("CARGO_PKG_VERSION_MAJOR"),
        env!("CARGO_PKG_VERSION_MINOR"),
        env!("CARGO_PKG_VERSION_PATCH"),
    );
    format!(
        r#"
/** Packs a version as returned by antumbra_version(). */
#define ANTUMBRA_MAKE_VERSION(major, minor, patch) \
    ((uint32_t)(((uint32_t)(major) << 16) | ((uint32_t)(minor) << 8) | (uint32_t)(patch)))
/** Major version of this header; a new major version may change the ABI (from 1.0 on). */
#define ANTUMBRA_VERSION_MAJOR {major}
/** Minor version of this header; before 1.0 a new minor version may change the ABI. */
#define ANTUMBRA_VERSION_MINOR {minor}
/** Patch version of this header; never changes the ABI. */
#define ANTUMBRA_VERSION_PATCH {patch}
/** Version of this header as a string, e.g. "0.1.0"; compare antumbra_version_string(). */
#define ANTUMBRA_VERSION_STRING "{major}.{minor}.{patch}"
/** Version of this header, packed as antumbra_version() returns the library's. */
#define ANTUMBRA_VERSION \
    ANTUMBRA_MAKE_VERSION(ANTUMBRA_VERSION_MAJOR, ANTUMBRA_VERSION_MINOR, ANTUMBRA_VERSION_PATCH)

/** Defined when the program links the hosted library (the default), which has
 *  every function; left undefined when the program defines ANTUMBRA_NO_STD
 *  before including this header, to link the bare-metal build (`cargo build -p
 *  antumbra-ffi --release --no-default-features --target thumbv7em-none-eabihf`).
 *  Declarations under `#if defined(ANTUMBRA_HAS_STD)` are not in the bare-metal
 *  library at all (a link error, never a run-time surprise); those under
 *  `#if !defined(ANTUMBRA_HAS_STD)` are only there: antumbra_set_allocator() and
 *  antumbra_set_panic_hook(). */
#if !defined(ANTUMBRA_NO_STD) && !defined(ANTUMBRA_HAS_STD)
#define ANTUMBRA_HAS_STD 1
#endif

/** Marks functions whose antumbra_result must be checked. In C, GCC still warns
 *  on `(void)f()`; write `(void)!f()` to discard a result on purpose. */
#if defined(__cplusplus) && __cplusplus >= 201703L
#define ANTUMBRA_NODISCARD [[nodiscard]]
#elif defined(__GNUC__) || defined(__clang__)
#define ANTUMBRA_NODISCARD __attribute__((warn_unused_result))
#else
#define ANTUMBRA_NODISCARD
#endif
"#
    )
}

fn generate() -> String {
    let crate_dir = env!("CARGO_MANIFEST_DIR");
    let mut config = cbindgen::Config::from_file(Path::new(crate_dir).join("cbindgen.toml"))
        .expect("ffi/cbindgen.toml is readable");
    config.after_includes = Some(after_includes());
    let mut bytes = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen can parse ffi/src")
        .write(&mut bytes);
    String::from_utf8(bytes).expect("header is UTF-8")
}

#[test]
fn committed_header_is_current() {
    let path = repo_root().join("include/antumbra.h");
    let fresh = generate();
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if std::env::var_os("ANTUMBRA_BLESS").is_some_and(|v| v == "1") {
        if committed != fresh {
            std::fs::write(&path, &fresh).expect("write include/antumbra.h");
            eprintln!("rewrote {}", path.display());
        }
        return;
    }
    if committed != fresh {
        let diff = line_diff(&committed, &fresh);
        panic!(
            "include/antumbra.h is stale. Regenerate it with\n    \
             ANTUMBRA_BLESS=1 cargo test -p antumbra-ffi --test header\n\
             and commit it. Differences (- committed, + generated):\n{diff}"
        );
    }
}

/// A minimal line diff: enough to show what changed without a diff dependency.
fn line_diff(old: &str, new: &str) -> String {
    let old: Vec<&str> = old.lines().collect();
    let new: Vec<&str> = new.lines().collect();
    // Longest common subsequence table, then walk it.
    let mut lcs = vec![vec![0u32; new.len() + 1]; old.len() + 1];
    for i in (0..old.len()).rev() {
        for j in (0..new.len()).rev() {
            lcs[i][j] = if old[i] == new[j] {
                lcs[i + 1][j + 1] + 1
            } else {
                lcs[i + 1][j].max(lcs[i][j + 1])
            };
        }
    }
    let (mut i, mut j, mut out) = (0, 0, String::new());
    while i < old.len() || j < new.len() {
        if i < old.len() && j < new.len() && old[i] == new[j] {
            i += 1;
            j += 1;
        } else if j < new.len() && (i == old.len() || lcs[i][j + 1] >= lcs[i + 1][j]) {
            out += &format!("+ {}\n", new[j]);
            j += 1;
        } else {
            out += &format!("- {}\n", old[i]);
            i += 1;
        }
    }
    out
}
