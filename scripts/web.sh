#!/usr/bin/env bash
# Builds the web page (docs/WEB.md): troupe-web (bindings/web) for wasm32-unknown-unknown with
# SIMD, its JavaScript glue by wasm-bindgen, and the files the page loads, into web/pkg/:
#
#   troupe_web.js, troupe_web_bg.wasm   the module and its glue (wasm-bindgen --target web)
#   draw.js                             the player's drawing (src/viewer/draw.js)
#   armflow-demo.tar                    the demo bundle (onnx/bundles/armflow-demo, its graphs)
#   cmu-playground-120fps.npy           the actor clip (tests/data/mocap)
#
# Then any static file server shows it: `python3 -m http.server -d web` and open
# http://127.0.0.1:8000/. Installs what it needs first, into caches under target/: the
# wasm32-unknown-unknown standard library (rustup) and wasm-bindgen-cli, pinned to the version of
# the wasm-bindgen crate in bindings/web/Cargo.lock (they must match).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
    echo "== web: rustup target add wasm32-unknown-unknown" >&2
    rustup target add wasm32-unknown-unknown >&2
fi

version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/[^0-9.]/, ""); print; exit }' \
    bindings/web/Cargo.lock)
tools=$root/target/tools
bindgen=$tools/bin/wasm-bindgen
if [ ! -x "$bindgen" ] || [ "$("$bindgen" --version | awk '{print $2}')" != "$version" ]; then
    echo "== web: cargo install wasm-bindgen-cli $version (a few minutes, once)" >&2
    started=$SECONDS
    # Only the `wasm-bindgen` program, without the TLS stack its test runner downloads browser
    # drivers with (rustls and ring); and not through clippy, should the caller lint its own
    # builds with it (scripts/test.sh).
    env -u RUSTC_WORKSPACE_WRAPPER -u CLIPPY_ARGS \
        cargo install --quiet wasm-bindgen-cli --version "=$version" --root "$tools" \
        --no-default-features --bin wasm-bindgen >&2
    echo "== web: wasm-bindgen-cli installed in $((SECONDS - started)) s" >&2
fi

echo "== web: building troupe-web (wasm32, simd128)" >&2
started=$SECONDS
(cd bindings/web && CARGO_TARGET_DIR=$root/target/web-build cargo build --release --locked >&2)
echo "== web: troupe-web built in $((SECONDS - started)) s" >&2
wasm=$root/target/web-build/wasm32-unknown-unknown/release/troupe_web.wasm

out=web/pkg
rm -rf "$out.tmp"
mkdir -p "$out.tmp"
# Without the function names (stack traces' only use for them): 5 MB less to download.
"$bindgen" --target web --no-typescript --remove-name-section --remove-producers-section --out-dir "$out.tmp" "$wasm"
cp src/viewer/draw.js "$out.tmp/draw.js"
scripts/bundle-tar.sh onnx/bundles/armflow-demo "$out.tmp/armflow-demo.tar"
cp tests/data/mocap/cmu-playground-120fps.npy "$out.tmp/"
rm -rf "$out"
mv "$out.tmp" "$out"

size() { wc -c < "$1" | tr -d ' '; }
gz() { gzip -9 -c "$1" | wc -c | tr -d ' '; }
for f in "$out/troupe_web_bg.wasm" "$out/armflow-demo.tar"; do
    echo "$f: $(size "$f") bytes, $(gz "$f") gzipped" >&2
done
