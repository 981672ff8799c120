#!/usr/bin/env bash
# Packs a bundle folder into one tar archive, the form troupe_model_load_memory and the loader
# of `.tar` paths read: the folder's files at the archive's top, in name order, with fixed
# owners and times, so the same bundle always gives the same bytes. Used for the web page's
# model (scripts/web.sh), the Unity sample's TextAsset (scripts/install.sh) and its test.
#
#   scripts/bundle-tar.sh BUNDLE_DIR OUT.tar
set -euo pipefail
[ "$#" -eq 2 ] && [ -f "$1/troupe.json" ] || { echo "usage: bundle-tar.sh BUNDLE_DIR OUT.tar (a folder with troupe.json)" >&2; exit 2; }
files=$(mktemp)
trap 'rm -f "$files"' EXIT
(cd "$1" && find . -maxdepth 1 -type f -printf '%P\n' | LC_ALL=C sort) >"$files"
tar --format=ustar --owner=0 --group=0 --numeric-owner --mtime=@0 -cf "$2" -C "$1" -T "$files"
