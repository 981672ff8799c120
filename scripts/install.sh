#!/usr/bin/env bash
# Installs troupe as a C/C++ library into a prefix, the way a system package would:
#
#   scripts/install.sh --prefix /opt/troupe            # builds the release library first
#
#   PREFIX/lib/libtroupe.so.1                the shared library (SONAME libtroupe.so.1)
#   PREFIX/lib/libtroupe.so -> libtroupe.so.1  for -ltroupe at link time
#   PREFIX/lib/libtroupe.a                   the static library
#   PREFIX/include/troupe/troupe.h           the C header
#   PREFIX/include/troupe/troupe.hpp         the header-only C++ wrapper
#   PREFIX/lib/pkgconfig/troupe.pc           pkg-config, shared (Libs.private: the static link's)
#   PREFIX/lib/pkgconfig/troupe-static.pc    pkg-config, static
#   PREFIX/lib/cmake/troupe/troupeConfig.cmake, troupeConfigVersion.cmake
#                                            find_package(troupe 0.2): troupe::troupe (shared),
#                                            troupe::troupe_static
#   PREFIX/share/troupe/bundles/armflow-demo the trained demo model
#
# For Windows x64 (--target x86_64-pc-windows-gnu, cross-built with MinGW-w64) the library is
#   PREFIX/bin/troupe.dll                    the DLL (beside the programs that load it)
#   PREFIX/lib/libtroupe.dll.a               its import library for MinGW (-ltroupe)
#   PREFIX/lib/troupe.def                    its exports, for an MSVC import library:
#                                            lib /def:troupe.def /machine:x64 /out:troupe.lib
#   PREFIX/lib/libtroupe.a                   the static library (MinGW)
# with the same headers, bundles, pkg-config file (troupe.pc) and CMake package (troupe::troupe
# imports the DLL through its import library); docs/PLATFORMS.md.
#
# Options:
#   --prefix DIR       where to install (required)
#   --profile NAME     the Cargo profile to build with: release (default), dist (release with
#                      link-time optimisation, one codegen unit, symbols stripped: smaller and
#                      what a package should ship, a longer build), or dev
#   --features LIST    Cargo features, as `cargo build --features` takes them
#   --target TRIPLE    cross-build for another target: aarch64-unknown-linux-gnu (Linux arm64)
#                      or x86_64-pc-windows-gnu (Windows x64); default: this machine
#   --no-build         install what the profile's last build left in target/
#   --unity-package DIR
#                      also write the Unity package to DIR: unity/ (its manifest, assembly
#                      definition and sample) with the C# binding (bindings/csharp/Troupe.cs)
#                      in Runtime/ and the library in Runtime/Plugins/x86_64/ (ARM64/ for
#                      Linux arm64; troupe.dll for Windows). Given a package it wrote before
#                      for this release, it keeps the other platforms' plugins there: run it
#                      once per --target to gather them in one package
#
# Every file installed is relocatable: the pkg-config and CMake files find the prefix from
# their own location, so the prefix may be moved or packed as it is. The shared library's
# SONAME carries the C ABI version (docs/ABI.md): a program linked against it asks for
# libtroupe.so.1 and never picks up an incompatible library.
set -euo pipefail
# Paths given relative are the caller's, not the repository's.
caller=$PWD
cd "$(dirname "$0")/.."
from_caller() { case "$1" in /*) echo "$1" ;; *) echo "$caller/$1" ;; esac; }

prefix= profile=release features= build=1 unity= target=
# An option's value: present and not empty, else a usage error (exit status 2).
value() { [ "$#" -ge 2 ] && [ -n "$2" ] || { echo "install.sh: $1 needs a value" >&2; exit 2; }; }
while [ "$#" -gt 0 ]; do
    case "$1" in
        --prefix) value "$@"; prefix=$(from_caller "$2"); shift 2 ;;
        --profile) value "$@"; profile=$2; shift 2 ;;
        --features) value "$@"; features=$2; shift 2 ;;
        --target) value "$@"; target=$2; shift 2 ;;
        --no-build) build=; shift ;;
        --unity-package) value "$@"; unity=$(from_caller "$2"); shift 2 ;;
        -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
        *) echo "install.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done
[ -n "$prefix" ] || { echo "install.sh: --prefix DIR is required" >&2; exit 2; }
# The Unity package folder is replaced whole, so only ever an earlier copy of that package.
if [ -n "$unity" ] && [ -e "$unity" ] && ! grep -qs '"name": "com.troupe.runtime"' "$unity/package.json"; then
    echo "install.sh: $unity exists and is not a troupe Unity package; give a new folder" >&2
    exit 2
fi
case "$(uname -s)" in
    Linux) ;;
    *) echo "install.sh: runs on Linux only so far (docs/INSTALL.md)" >&2; exit 2 ;;
esac
case "$target" in
    "" | x86_64-unknown-linux-gnu | aarch64-unknown-linux-gnu) windows= ;;
    x86_64-pc-windows-gnu) windows=1 ;;
    *) echo "install.sh: no install layout for target $target (docs/PLATFORMS.md)" >&2; exit 2 ;;
esac

# The library's release (Cargo.toml) and the C ABI's major version (src/ffi/version.rs).
version=$(sed -n 's/^version = "\(.*\)"$/\1/p' Cargo.toml | head -n1)
abi=$(sed -n 's/^pub const TROUPE_ABI_VERSION: u32 = \([0-9]*\);$/\1/p' src/ffi/version.rs)
[ -n "$version" ] && [ -n "$abi" ] || { echo "install.sh: cannot read the version" >&2; exit 1; }

if [ -n "$build" ]; then
    echo "== building the library (cargo build --profile $profile --lib${target:+ --target $target})"
    cargo build --profile "$profile" --lib ${features:+--features "$features"} \
        ${target:+--target "$target"}
fi
out_dir=${CARGO_TARGET_DIR:-target}${target:+/$target}/$([ "$profile" = dev ] && echo debug || echo "$profile")
if [ -n "$windows" ]; then
    built="troupe.dll libtroupe.dll.a libtroupe.a"
else
    built="libtroupe.so libtroupe.a"
fi
for f in $built; do
    [ -f "$out_dir/$f" ] || { echo "install.sh: $out_dir/$f is missing (build it, or drop --no-build)" >&2; exit 1; }
done

# What the static library needs besides itself: the system libraries Rust's standard library
# links on Linux with glibc (rustc --print native-static-libs), and a non-executable stack,
# which the linker would otherwise not infer: some of tract's assembly objects carry no
# .note.GNU-stack section.
static_libs="-lgcc_s -lutil -lrt -lpthread -lm -ldl -lc"
static_flags="-Wl,-z,noexecstack"

# The Unity package, with the library file `$1` of the build in its plugin folder. A package this
# script wrote before for the same release keeps the plugins of the other platforms it holds:
# running it once per --target gathers every platform built here into one package.
write_unity() {
    local plugins=x86_64 kept
    [ "$target" = aarch64-unknown-linux-gnu ] && plugins=ARM64
    kept=$(mktemp -d)
    if [ -d "$unity/Runtime/Plugins" ] && grep -qs "\"version\": \"$version\"" "$unity/package.json"; then
        cp -R "$unity/Runtime/Plugins/." "$kept/"
        find "$kept" -name '*.meta' -delete
    fi
    rm -rf "$unity"
    mkdir -p "$unity"
    cp -R unity/. "$unity/"
    # The binding is kept once, in bindings/csharp; the package gets its copy here.
    install -m 644 bindings/csharp/Troupe.cs "$unity/Runtime/Troupe.cs"
    mkdir -p "$unity/Runtime/Plugins"
    cp -R "$kept/." "$unity/Runtime/Plugins/"
    rm -rf "$kept"
    mkdir -p "$unity/Runtime/Plugins/$plugins"
    install -m 755 "$out_dir/$1" "$unity/Runtime/Plugins/$plugins/$1"
    # The demo model as one archive the sample loads from bytes (a TextAsset: every platform,
    # Android's compressed StreamingAssets included).
    scripts/bundle-tar.sh onnx/bundles/armflow-demo "$unity/Samples~/AnimatorPartner/armflow-demo.bytes"
    # The assembly compiles where a library is: the editor and the players of the plugins present.
    local plugin platform os cpu asm_player players=() platforms='"Editor"' present=()
    for plugin in "$unity"/Runtime/Plugins/*/*; do
        platform=$(unity_platform "${plugin#"$unity/"}") ||
            { echo "install.sh: $plugin is no plugin this script writes" >&2; exit 1; }
        read -r os cpu _ asm_player <<<"$platform"
        present+=("$os $cpu")
        case " ${players[*]} " in *" $asm_player "*) ;; *) players+=("$asm_player") ;; esac
    done
    for asm_player in "${players[@]}"; do platforms="$platforms, \"$asm_player\""; done
    sed -i "s/\"includePlatforms\": \[[^]]*\]/\"includePlatforms\": [$platforms]/" \
        "$unity/Runtime/Troupe.Runtime.asmdef"
    unity_metas "$unity"
    echo "unity package: $unity (com.troupe.runtime $version; plugins: $(IFS=,; echo "${present[*]}"))"
}

# A plugin's platform, from its place in the package: its OS and CPU as the importer names them,
# its standalone player, and the asmdef's name for that player.
unity_platform() {
    case "$1" in
        Runtime/Plugins/x86_64/libtroupe.so) echo "Linux x86_64 Linux64 LinuxStandalone64" ;;
        Runtime/Plugins/ARM64/libtroupe.so) echo "Linux ARM64 Linux64 LinuxStandalone64" ;;
        Runtime/Plugins/x86_64/troupe.dll) echo "Windows x86_64 Win64 WindowsStandalone64" ;;
        *) return 1 ;;
    esac
}

# Unity finds a package's assets by the GUIDs in their `.meta` files, and regenerates missing
# ones with new GUIDs in every project (breaking references to them): each file and folder gets
# one here, its GUID derived from its path in the package, so it is the same in every install.
# Folders ending in `~` (the samples) and hidden files are not imported, so they get none. Each
# plugin's importer settings enable it for the editor and the player of its OS and CPU only.
unity_guid() { printf 'com.troupe.runtime/%s' "$1" | md5sum | cut -c1-32; }
unity_metas() {
    local root=$1 rel guid paths platform
    # Listed before any .meta is written, so that none gets a .meta of its own.
    mapfile -t paths < <(cd "$root" && find . -mindepth 1 \( -name '*~' -o -name '.*' \) -prune -o -print |
        sed 's|^\./||' | sort)
    for rel in "${paths[@]}"; do
            guid=$(unity_guid "$rel")
            {
                printf 'fileFormatVersion: 2\nguid: %s\n' "$guid"
                if [ -d "$root/$rel" ]; then
                    printf 'folderAsset: yes\nDefaultImporter:\n'
                elif platform=$(unity_platform "$rel"); then
                    # shellcheck disable=SC2086  (OS, CPU and player)
                    unity_plugin_importer $platform
                else
                    case "$rel" in
                        *.cs) printf 'MonoImporter:\n  serializedVersion: 2\n  defaultReferences: []\n  executionOrder: 0\n  icon: {instanceID: 0}\n' ;;
                        *.asmdef) printf 'AssemblyDefinitionImporter:\n' ;;
                        package.json) printf 'PackageManifestImporter:\n' ;;
                        *) printf 'TextScriptImporter:\n' ;;
                    esac
                fi
                printf '  externalObjects: {}\n  userData: \n  assetBundleName: \n  assetBundleVariant: \n'
            } >"$root/$rel.meta"
    done
}
unity_plugin_importer() {
    local os=$1 cpu=$2 player=$3 p
    printf 'PluginImporter:\n  serializedVersion: 2\n  iconMap: {}\n  executionOrder: {}\n'
    printf '  defineConstraints: []\n  isPreloaded: 0\n  isOverridable: 0\n'
    printf '  isExplicitlyReferenced: 0\n  validateReferences: 1\n  platformData:\n'
    printf '  - first:\n      : Any\n    second:\n      enabled: 0\n      settings:\n'
    printf '        Exclude Editor: 0\n'
    for p in Linux64 OSXUniversal Win64; do
        printf '        Exclude %s: %s\n' "$p" "$([ "$p" = "$player" ] && echo 0 || echo 1)"
    done
    printf '  - first:\n      Any: \n    second:\n      enabled: 0\n      settings: {}\n'
    printf '  - first:\n      Editor: Editor\n    second:\n      enabled: 1\n      settings:\n'
    printf '        CPU: %s\n        DefaultValueInitialized: true\n        OS: %s\n' "$cpu" "$os"
    for p in Linux64 OSXUniversal Win64; do
        printf '  - first:\n      Standalone: %s\n    second:\n      enabled: %s\n      settings:\n' \
            "$p" "$([ "$p" = "$player" ] && echo 1 || echo 0)"
        printf '        CPU: %s\n' "$([ "$p" = "$player" ] && echo "$cpu" || echo None)"
    done
}
du_of() { du -k "$1" | cut -f1; }

# The Windows layout: the DLL in bin/, its MinGW import library and an MSVC .def in lib/, and
# pkg-config and CMake files that import the DLL through the import library.
install_windows() {
    mkdir -p "$prefix/bin"
    install -m 755 "$out_dir/troupe.dll" "$prefix/bin/troupe.dll"
    install -m 644 "$out_dir/libtroupe.dll.a" "$lib/libtroupe.dll.a"
    {
        echo "LIBRARY troupe.dll"
        echo "EXPORTS"
        grep -v '^#' abi/troupe.symbols | sed 's/^/    /'
    } >"$lib/troupe.def"
    cat >"$lib/pkgconfig/troupe.pc" <<EOF
prefix=\${pcfiledir}/../..
libdir=\${prefix}/lib
includedir=\${prefix}/include/troupe
bundledir=\${prefix}/share/troupe/bundles

Name: troupe
Description: Real-time human interaction motion generation (C ABI $abi, Windows x64 DLL)
Version: $version
Cflags: -I\${prefix}/include -I\${includedir}
Libs: \${libdir}/libtroupe.dll.a
EOF
    rm -f "$lib/pkgconfig/troupe-static.pc"
    cat >"$lib/cmake/troupe/troupeConfig.cmake" <<EOF
# troupe's CMake package for Windows x64 (scripts/install.sh --target x86_64-pc-windows-gnu).
# find_package(troupe $version) gives troupe::troupe: bin/troupe.dll, imported through
# lib/libtroupe.dll.a (MinGW); with MSVC, make troupe.lib from lib/troupe.def and set the
# target's IMPORTED_IMPLIB to it. troupe_BUNDLE_DIR: the installed models.
get_filename_component(_troupe_prefix "\${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
set(troupe_LIBRARY_VERSION "$version")
set(troupe_BUNDLE_DIR "\${_troupe_prefix}/share/troupe/bundles")
if(NOT TARGET troupe::troupe)
    add_library(troupe::troupe SHARED IMPORTED)
    set_target_properties(troupe::troupe PROPERTIES
        IMPORTED_LOCATION "\${_troupe_prefix}/bin/troupe.dll"
        IMPORTED_IMPLIB "\${_troupe_prefix}/lib/libtroupe.dll.a"
        INTERFACE_INCLUDE_DIRECTORIES "\${_troupe_prefix}/include;\${_troupe_prefix}/include/troupe")
endif()
unset(_troupe_prefix)
EOF
    write_config_version
    if [ -n "$unity" ]; then
        write_unity troupe.dll
    fi
    echo "installed: troupe.dll $(du_of "$prefix/bin/troupe.dll") KiB," \
        "libtroupe.dll.a $(du_of "$lib/libtroupe.dll.a") KiB, libtroupe.a $(du_of "$lib/libtroupe.a") KiB"
}

# The CMake package's version file, the same for every target.
write_config_version() {
cat >"$lib/cmake/troupe/troupeConfigVersion.cmake" <<EOF
# The package's version is the library's release ($version). Every release from 0.1 on speaks
# C ABI $abi (docs/ABI.md), so a request for an older or equal 0.x release is met by this one;
# a request for a newer release is not. A request for the ABI number itself ($abi, what the 0.1
# package was versioned by) is met too, as the SONAME libtroupe.so.$abi promises; once releases
# reach 1.0 the release's major number is the ABI's.
set(PACKAGE_VERSION "$version")
if(PACKAGE_FIND_VERSION STREQUAL "")
    set(PACKAGE_VERSION_COMPATIBLE TRUE)
elseif(PACKAGE_FIND_VERSION_MAJOR EQUAL 0)
    if(PACKAGE_FIND_VERSION_MINOR GREATER_EQUAL 1 AND NOT PACKAGE_FIND_VERSION VERSION_GREATER PACKAGE_VERSION)
        set(PACKAGE_VERSION_COMPATIBLE TRUE)
    else()
        set(PACKAGE_VERSION_COMPATIBLE FALSE)
    endif()
elseif(PACKAGE_FIND_VERSION_MAJOR EQUAL $abi AND PACKAGE_FIND_VERSION_COUNT EQUAL 1)
    set(PACKAGE_VERSION_COMPATIBLE TRUE)
else()
    set(PACKAGE_VERSION_COMPATIBLE FALSE)
endif()
if(PACKAGE_FIND_VERSION STREQUAL PACKAGE_VERSION)
    set(PACKAGE_VERSION_EXACT TRUE)
endif()
# A project without languages has no pointer size: only a known one that differs is refused.
if(NOT "\${CMAKE_SIZEOF_VOID_P}" STREQUAL "" AND NOT CMAKE_SIZEOF_VOID_P STREQUAL "8")
    set(PACKAGE_VERSION "\${PACKAGE_VERSION} (64-bit)")
    set(PACKAGE_VERSION_UNSUITABLE TRUE)
endif()
EOF
}

prefix=$(mkdir -p "$prefix" && cd "$prefix" && pwd)
lib=$prefix/lib include=$prefix/include/troupe
mkdir -p "$lib/pkgconfig" "$lib/cmake/troupe" "$include" "$prefix/share/troupe/bundles"
echo "== installing troupe $version (C ABI $abi) into $prefix"

install -m 644 "$out_dir/libtroupe.a" "$lib/libtroupe.a"
install -m 644 include/troupe.h bindings/cpp/troupe.hpp "$include/"
rm -rf "$prefix/share/troupe/bundles/armflow-demo"
cp -R onnx/bundles/armflow-demo "$prefix/share/troupe/bundles/"
if [ -n "$windows" ]; then
    install_windows
    exit 0
fi
install -m 755 "$out_dir/libtroupe.so" "$lib/libtroupe.so.$abi"
ln -sf "libtroupe.so.$abi" "$lib/libtroupe.so"

cat >"$lib/pkgconfig/troupe.pc" <<EOF
prefix=\${pcfiledir}/../..
libdir=\${prefix}/lib
includedir=\${prefix}/include/troupe
bundledir=\${prefix}/share/troupe/bundles

Name: troupe
Description: Real-time human interaction motion generation (C ABI $abi)
Version: $version
Cflags: -I\${prefix}/include -I\${includedir}
Libs: -L\${libdir} -ltroupe
Libs.private: $static_flags $static_libs
EOF

cat >"$lib/pkgconfig/troupe-static.pc" <<EOF
prefix=\${pcfiledir}/../..
libdir=\${prefix}/lib
includedir=\${prefix}/include/troupe
bundledir=\${prefix}/share/troupe/bundles

Name: troupe-static
Description: Real-time human interaction motion generation, linked statically (C ABI $abi)
Version: $version
Cflags: -I\${prefix}/include -I\${includedir}
Libs: \${libdir}/libtroupe.a $static_flags $static_libs
EOF

cat >"$lib/cmake/troupe/troupeConfig.cmake" <<EOF
# troupe's CMake package (scripts/install.sh). find_package(troupe $version) gives:
#   troupe::troupe          the shared library, libtroupe.so.$abi
#   troupe::troupe_static   the static library with the system libraries it needs
#   troupe_VERSION          the C ABI version the package is found by ($abi)
#   troupe_LIBRARY_VERSION  the library's release ($version)
#   troupe_BUNDLE_DIR       the installed models (armflow-demo)
get_filename_component(_troupe_prefix "\${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
set(troupe_LIBRARY_VERSION "$version")
set(troupe_BUNDLE_DIR "\${_troupe_prefix}/share/troupe/bundles")
if(NOT TARGET troupe::troupe)
    add_library(troupe::troupe SHARED IMPORTED)
    set_target_properties(troupe::troupe PROPERTIES
        IMPORTED_LOCATION "\${_troupe_prefix}/lib/libtroupe.so.$abi"
        IMPORTED_SONAME "libtroupe.so.$abi"
        INTERFACE_INCLUDE_DIRECTORIES "\${_troupe_prefix}/include;\${_troupe_prefix}/include/troupe")
endif()
if(NOT TARGET troupe::troupe_static)
    find_package(Threads REQUIRED)
    add_library(troupe::troupe_static STATIC IMPORTED)
    set_target_properties(troupe::troupe_static PROPERTIES
        IMPORTED_LOCATION "\${_troupe_prefix}/lib/libtroupe.a"
        INTERFACE_INCLUDE_DIRECTORIES "\${_troupe_prefix}/include;\${_troupe_prefix}/include/troupe"
        INTERFACE_LINK_LIBRARIES "Threads::Threads;\${CMAKE_DL_LIBS};m;rt;util;gcc_s"
        INTERFACE_LINK_OPTIONS "LINKER:-z,noexecstack")
endif()
unset(_troupe_prefix)
EOF

write_config_version

if [ -n "$unity" ]; then
    write_unity libtroupe.so
fi
echo "installed: libtroupe.so.$abi $(du_of "$lib/libtroupe.so.$abi") KiB, libtroupe.a $(du_of "$lib/libtroupe.a") KiB"
