//! Paths that mean the same on every platform.
//!
//! Windows gives some names a meaning of their own in every folder: `CON`, `NUL`, `COM1`, ...
//! (with any extension: `nul.json` too) open a device, not a file, and `\\.\` paths name devices
//! directly. Opening one can block (the console waits for a keypress) or read without end, so on
//! Windows troupe refuses such a path before opening or writing it, as it refuses FIFOs and
//! devices on Unix. A bundle's own file names avoid them on every platform, and avoid `\` and `:`
//! as well (a separator, a drive or an alternate data stream on Windows, plain characters
//! elsewhere): a bundle then names the same files wherever it is loaded.

use std::path::Path;

/// Whether a path component is a name Windows reserves for a device: its part before the first
/// `.` or `:`, less trailing spaces, is `CON`, `PRN`, `AUX`, `NUL`, `COM0`-`COM9`, `LPT0`-`LPT9`
/// (superscript digits included), `CONIN$` or `CONOUT$`, in any case.
pub(crate) fn is_device_name(component: &str) -> bool {
    let stem = component
        .split(['.', ':'])
        .next()
        .unwrap_or("")
        .trim_end_matches(' ')
        .to_ascii_uppercase();
    match stem.as_str() {
        "CON" | "PRN" | "AUX" | "NUL" | "CONIN$" | "CONOUT$" => true,
        _ => {
            let (port, digit) = match (stem.get(..3), stem.get(3..)) {
                (Some(port), Some(digit)) => (port, digit),
                _ => return false,
            };
            matches!(port, "COM" | "LPT")
                && matches!(
                    digit,
                    "0" | "1" | "2" | "3" | "4" | "5" | "6" | "7" | "8" | "9" | "¹" | "²" | "³"
                )
        }
    }
}

/// The device a path names under Windows' rules, if any: a `\\.\` or `\\?\GLOBALROOT` path, or a
/// component that is a reserved device name ([`is_device_name`]). Both separators count.
pub(crate) fn windows_device_in(path: &str) -> Option<String> {
    let normalized = path.replace('/', "\\");
    let upper = normalized.to_ascii_uppercase();
    if upper.starts_with("\\\\.\\") || upper.starts_with("\\\\?\\GLOBALROOT") {
        return Some(path.to_string());
    }
    normalized
        .split('\\')
        .find(|part| is_device_name(part))
        .map(str::to_string)
}

/// The device `path` names under Windows' rules, on Windows (see the module documentation);
/// elsewhere every name is an ordinary name, and the file-type checks that follow (no FIFO, no
/// device) apply. The callers refuse a device as they refuse any other special file.
pub(crate) fn windows_device(path: &Path) -> Option<String> {
    if cfg!(windows) {
        windows_device_in(&path.to_string_lossy())
    } else {
        None
    }
}

/// How a refused device is described in messages.
pub(crate) fn device_message(device: &str) -> String {
    format!("the path names the Windows device `{device}`, not a file")
}

/// Whether `part` (one component of a bundle's file name) means the same file on every
/// platform: no `\` or `:`, not a reserved device name.
pub(crate) fn is_portable_name(part: &str) -> bool {
    !part.contains(['\\', ':']) && !is_device_name(part)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_names_are_recognised_with_any_extension_or_case() {
        for name in [
            "NUL",
            "nul",
            "Nul.json",
            "con",
            "CON.txt.bak",
            "aux ",
            "PRN .x",
            "com1",
            "LPT9.onnx",
            "COM¹",
            "conin$",
            "CONOUT$",
            "nul:",
        ] {
            assert!(is_device_name(name), "{name}");
        }
        for name in [
            "null",
            "console",
            "COM",
            "COM10",
            "LPT",
            "auxiliary",
            "xnul",
            "vae.onnx",
            "troupe.json",
            "",
        ] {
            assert!(!is_device_name(name), "{name}");
        }
    }

    #[test]
    fn windows_device_paths_are_found_in_any_component_with_either_separator() {
        for path in [
            "NUL",
            "C:\\bundles\\nul.json",
            "C:/bundles/CON",
            "\\\\.\\PhysicalDrive0",
            "//./nul",
            "\\\\?\\GLOBALROOT\\Device\\Null",
            "bundles\\com3\\troupe.json",
        ] {
            assert!(windows_device_in(path).is_some(), "{path}");
        }
        for path in [
            "C:\\bundles\\armflow-demo",
            "\\\\?\\C:\\bundles\\x",
            "\\\\server\\share\\bundle.troupe",
            "Z:\\tmp\\bündel\\troupe.json",
            "/home/null/bundle",
        ] {
            assert_eq!(windows_device_in(path), None, "{path}");
        }
    }

    #[test]
    fn portable_names_exclude_separators_drives_streams_and_devices() {
        assert!(is_portable_name("vae.onnx"));
        assert!(is_portable_name("gewichte-ü.onnx"));
        for part in ["a\\b", "C:x", "vae.onnx:stream", "NUL", "aux.onnx"] {
            assert!(!is_portable_name(part), "{part}");
        }
    }

    #[test]
    fn only_windows_has_device_names() {
        assert_eq!(windows_device(Path::new("NUL")).is_some(), cfg!(windows));
        assert_eq!(windows_device(Path::new("bundles/armflow-demo")), None);
    }
}
