//! Builds the C drive firmware (`../../firmware`, the fracfw library) for the host and links it
//! into this crate, so the simulator can run the C protocol engine ([`sim::FirmwareKind::C`]).
//! Uses the system C compiler (`$CC`, default `cc`) and `ar` directly: the two files need nothing
//! more. Undefined behaviour in the C code traps (`-fsanitize=undefined` in trap mode, no runtime
//! library needed); the strict warning set and ASan run in `firmware/test.sh`.
//!
//! The C firmware's protocol header `fw_protocol.h` is generated here from the description of the
//! frames (`src/protocol/spec.rs`) and put ahead of `firmware/include` on the include path, so
//! the linked firmware always speaks the table's protocol; the copy in `firmware/include` (for
//! `firmware/test.sh` and the F2812 build) is checked against it by a test of the crate.

use std::path::PathBuf;
use std::process::Command;

#[allow(dead_code)]
#[path = "src/protocol/spec.rs"]
mod spec;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let fw = manifest.join("../../firmware");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets it"));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let include = fw.join("include");
    let spec_src = manifest.join("src/protocol/spec.rs");
    println!("cargo:rerun-if-changed={}", spec_src.display());
    let generated = out.join("generated");
    std::fs::create_dir_all(&generated).expect("OUT_DIR is writable");
    std::fs::write(generated.join("fw_protocol.h"), spec::c_header())
        .expect("write the generated protocol header");
    println!(
        "cargo:rerun-if-changed={}",
        include.join("fracfw.h").display()
    );
    println!("cargo:rerun-if-env-changed=CC");
    let mut objs = Vec::new();
    for name in ["fw_codec", "fw_engine", "fw_ctrl"] {
        let src = fw.join("src").join(format!("{name}.c"));
        println!("cargo:rerun-if-changed={}", src.display());
        let obj = out.join(format!("{name}.o"));
        let status = Command::new(&cc)
            .args(["-std=c99", "-O2", "-fPIC", "-Wall", "-Wextra", "-pedantic"])
            .args(["-fsanitize=undefined", "-fsanitize-undefined-trap-on-error"])
            .arg("-I")
            .arg(&generated)
            .arg("-I")
            .arg(&include)
            .arg("-c")
            .arg(&src)
            .arg("-o")
            .arg(&obj)
            .status()
            .unwrap_or_else(|e| panic!("cannot run the C compiler {cc}: {e}"));
        assert!(status.success(), "compiling {} failed", src.display());
        objs.push(obj);
    }
    println!(
        "cargo:rerun-if-changed={}",
        fw.join("src/fw_sine_table.h").display()
    );
    let lib = out.join("libfracfw.a");
    let _ = std::fs::remove_file(&lib);
    let status = Command::new("ar")
        .arg("crs")
        .arg(&lib)
        .args(&objs)
        .status()
        .unwrap_or_else(|e| panic!("cannot run ar: {e}"));
    assert!(status.success(), "ar failed");
    println!("cargo:rustc-link-search=native={}", out.display());
    println!("cargo:rustc-link-lib=static=fracfw");
}
