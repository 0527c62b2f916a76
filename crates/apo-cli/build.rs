//! With the `mujoco3` feature, records the folder of `libmujoco.so.3.17.0`
//! (`MUJOCO_DYNAMIC_LINK_DIR`, which mujoco-rs links from) as the run path of `apo` and of this
//! crate's tests and examples, so that they start without `LD_LIBRARY_PATH`.

fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    if std::env::var_os("CARGO_FEATURE_MUJOCO3").is_none() {
        return;
    }
    if let Some(dir) = std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR") {
        let dir = dir.to_string_lossy();
        // The bins, tests, examples and benches of this package (not its library).
        println!("cargo::rustc-link-arg=-Wl,-rpath,{dir}");
    }
}
