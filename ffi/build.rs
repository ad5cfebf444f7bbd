//! Gives `libantumbra.so` its soname, so that programs linked against it record the
//! ABI they were built for (see CHANGELOG.md, "Versioning"): `libantumbra.so.0.<minor>`
//! before 1.0, when every minor release may change the ABI, and
//! `libantumbra.so.<major>` from 1.0 on.

fn main() {
    let major = std::env::var("CARGO_PKG_VERSION_MAJOR").expect("cargo sets the version");
    let minor = std::env::var("CARGO_PKG_VERSION_MINOR").expect("cargo sets the version");
    let soname = if major == "0" {
        format!("libantumbra.so.0.{minor}")
    } else {
        format!("libantumbra.so.{major}")
    };
    let target_os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    // Only ELF linkers take -soname; other platforms name their libraries otherwise.
    if matches!(
        target_os.as_str(),
        "linux" | "android" | "freebsd" | "netbsd" | "openbsd"
    ) {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,{soname}");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
