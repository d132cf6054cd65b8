#!/usr/bin/env bash
# Everything CI checks, in the same order: a green run here means a green CI.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --all -- --check
# Inside core, lower modules never use higher ones (docs/architecture.md): fails fast, and
# prints which module uses which.
cargo test -p thicket-core --test layers -- --nocapture
cargo clippy --workspace --all-targets -- -D warnings
# Doc links must resolve (a renamed item otherwise leaves a dead link in the API docs).
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --workspace --quiet
# The core crate must stay free of GPU and UI crates (ARCHITECTURE.md: app -> core only).
forbidden='^(wgpu|wgpu-core|wgpu-hal|naga|egui|egui-wgpu|eframe|winit|rfd) v'
if cargo tree -p thicket-core -e normal,build,dev --prefix none | grep -E "$forbidden"; then
  echo "error: thicket-core depends on a GPU/UI crate (listed above)" >&2
  exit 1
fi
cargo test --workspace
