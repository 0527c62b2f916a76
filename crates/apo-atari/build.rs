//! Builds the Arcade Learning Environment's C++ core (no SDL, no Python) from the pinned
//! `ale-py` 0.12.1 source archive and this crate's C shim.
//!
//! The archive is read from `APO_ALE_ARCHIVE`, else from `<workspace>/.cache/ale_py-0.12.1.tar.gz`
//! (where `scripts/setup.sh --atari` downloads it); its SHA-256 is checked before it is unpacked
//! into `OUT_DIR`.

use std::io::Read;
use std::path::{Path, PathBuf};

const ARCHIVE: &str = "ale_py-0.12.1.tar.gz";
const SHA256: &str = "c503d574c5983e1063b451201ccb779d935919c0f6bf116fb0f4f8aa4c86d249";
const ROOT: &str = "ale_py-0.12.1";
/// SDL front ends, left out (no window, no sound).
const WITHOUT: [&str; 3] = ["SDL2.cpp", "ScreenSDL.cpp", "SoundSDL.cxx"];

fn main() {
    println!("cargo:rerun-if-env-changed=APO_ALE_ARCHIVE");
    println!("cargo:rerun-if-changed=src/shim.cpp");
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let archive = std::env::var_os("APO_ALE_ARCHIVE").map_or_else(
        || manifest.join("../../.cache").join(ARCHIVE),
        PathBuf::from,
    );
    println!("cargo:rerun-if-changed={}", archive.display());
    let bytes = std::fs::read(&archive).unwrap_or_else(|e| {
        panic!(
            "cannot read the ALE source archive {}: {e}. Run `bash scripts/setup.sh --atari` \
             (it downloads {ARCHIVE} from PyPI), or point APO_ALE_ARCHIVE at it",
            archive.display()
        )
    });
    let digest = sha256_hex(&bytes);
    assert!(
        digest == SHA256,
        "{} has SHA-256 {digest}, not the pinned {SHA256}: download it again",
        archive.display()
    );
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets it"));
    let src = out.join(ROOT).join("src");
    if !src.join("ale").join("ale_interface.cpp").exists() {
        let mut tar = tar::Archive::new(flate2::read::GzDecoder::new(&bytes[..]));
        tar.unpack(&out).expect("unpacking the ALE archive");
    }
    let generated = out.join("generated");
    std::fs::create_dir_all(&generated).expect("OUT_DIR is writable");
    let template = std::fs::read_to_string(src.join("ale/version.hpp.in")).expect("version.hpp.in");
    let version = template
        .replace("@ALE_VERSION@", "0.12.1")
        .replace("@ALE_VERSION_MAJOR@", "0")
        .replace("@ALE_VERSION_MINOR@", "12")
        .replace("@ALE_VERSION_PATCH@", "1")
        .replace("@ALE_VERSION_GIT_SHA@", "");
    std::fs::write(generated.join("version.hpp"), version).expect("writing version.hpp");

    let ale = src.join("ale");
    let mut files = vec![ale.join("ale_interface.cpp")];
    for dir in [
        "common",
        "emucore",
        "environment",
        "games",
        "games/supported",
    ] {
        files.extend(sources(&ale.join(dir)));
    }
    cc::Build::new()
        .cpp(true)
        .std("c++17")
        .opt_level(3)
        .warnings(false)
        // as ale-py's release build: its asserts (one refuses the negative int32 seeds that
        // ale-py passes) are compiled out
        .define("NDEBUG", None)
        .include(&src)
        .include(&generated)
        .files(&files)
        .file(manifest.join("src/shim.cpp"))
        .compile("ale");
    println!("cargo:rustc-link-lib=z");
    println!("cargo:rustc-link-lib=stdc++");
}

/// The C++ sources of `dir` (not its subfolders), sorted, without the SDL front ends.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            (name.ends_with(".cpp") || name.ends_with(".cxx")) && !WITHOUT.contains(&name)
        })
        .collect();
    files.sort();
    files
}

fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    let mut hasher = sha2::Sha256::new();
    let mut reader = bytes;
    let mut buf = [0u8; 1 << 16];
    loop {
        let n = reader.read(&mut buf).expect("reading memory");
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
