//! Generates the marching-hypercubes table at build time (see src/table_gen.rs).

#[allow(dead_code)]
#[path = "src/table_gen.rs"]
mod table_gen;

fn main() {
    println!("cargo:rerun-if-changed=src/table_gen.rs");
    println!("cargo:rerun-if-changed=build.rs");
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR set by cargo"));
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let table = table_gen::build_table(threads);
    std::fs::write(out.join("mc4_table.bin"), &table).expect("write table");
}
