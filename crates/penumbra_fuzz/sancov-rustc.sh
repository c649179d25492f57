#!/bin/sh
# RUSTC_WRAPPER for `cargo xtask fuzz`: compiles the crates under test with LLVM's
# SanitizerCoverage (edge counters, comparison operands), everything else as usual, so
# coverage measures the code under test and not the fuzzer, clap or proc macros.
rustc="$1"
shift
case " $* " in
*" --crate-type proc-macro "* | *" --crate-name build_script_"*) exec "$rustc" "$@" ;;
*" --crate-name penumbra_sdf "* | *" --crate-name penumbra_cinematic_core "* | \
*" --crate-name gltf "* | *" --crate-name gltf_json "* | *" --crate-name serde_json "*)
    exec "$rustc" "$@" -C passes=sancov-module \
        -C llvm-args=-sanitizer-coverage-level=3 \
        -C llvm-args=-sanitizer-coverage-inline-8bit-counters \
        -C llvm-args=-sanitizer-coverage-pc-table \
        -C llvm-args=-sanitizer-coverage-trace-compares \
        -C debug-assertions -C overflow-checks
    ;;
*) exec "$rustc" "$@" ;;
esac
