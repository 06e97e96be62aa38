//! The Android and iOS project files agree with the code they package: the library's
//! name and entry points, the icons and the launch settings, the build scripts in
//! place. (What can be built here is built by `scripts/mobile-libs.sh` and
//! `scripts/android-apk.sh`; this catches the files drifting from the code.)

use std::path::{Path, PathBuf};

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

fn read(path: &str) -> String {
    std::fs::read_to_string(repo(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn executable(path: &str) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(repo(path)).is_ok_and(|m| m.permissions().mode() & 0o111 != 0)
}

const ANDROID: &str = "http://schemas.android.com/apk/res/android";

#[test]
fn the_android_manifest_names_the_library_and_its_resources_exist() {
    let text = read("android/AndroidManifest.xml");
    let doc = roxmltree::Document::parse(&text).expect("the manifest is XML");
    let attr = |n: roxmltree::Node, a: &str| n.attribute((ANDROID, a)).map(str::to_string);
    let find = |tag: &str| {
        doc.descendants()
            .find(|n| n.has_tag_name(tag))
            .unwrap_or_else(|| panic!("no <{tag}>"))
    };
    // The NativeActivity loads lib<lib_name>.so: the app crate's library.
    let meta = doc
        .descendants()
        .find(|n| attr(*n, "name").as_deref() == Some("android.app.lib_name"))
        .expect("android.app.lib_name");
    let cargo = read("app/Cargo.toml");
    let lib = attr(meta, "value").expect("a value");
    assert!(cargo.contains(&format!("name = \"{lib}\"")), "lib {lib}");
    assert_eq!(
        attr(find("application"), "hasCode").as_deref(),
        Some("false")
    );
    assert_eq!(
        attr(find("activity"), "name").as_deref(),
        Some("android.app.NativeActivity")
    );
    let min: u32 = attr(find("uses-sdk"), "minSdkVersion")
        .and_then(|v| v.parse().ok())
        .expect("minSdkVersion");
    assert!(min >= 26, "Vulkan-capable devices from API 26");
    // The activity handles rotation itself (the session outlives a new surface size).
    let changes = attr(find("activity"), "configChanges").expect("configChanges");
    assert!(changes.contains("orientation") && changes.contains("screenSize"));
    for density in ["mdpi", "hdpi", "xhdpi", "xxhdpi", "xxxhdpi"] {
        let icon = repo(&format!("android/res/mipmap-{density}/ic_launcher.png"));
        assert!(icon.exists(), "{}", icon.display());
    }
    assert!(read("android/res/values/strings.xml").contains("app_name"));
    let platform = read("app/src/platform.rs");
    assert!(platform.contains("fn android_main") && platform.contains("paranoid_android"));
    assert!(executable("scripts/android-apk.sh") && executable("scripts/mobile-libs.sh"));
}

#[test]
fn the_ios_project_links_the_library_and_calls_its_entry_point() {
    let plist = read("ios/Palpa/Info.plist");
    let doc = roxmltree::Document::parse_with_options(
        &plist,
        roxmltree::ParsingOptions {
            allow_dtd: true,
            ..Default::default()
        },
    )
    .expect("Info.plist is XML");
    let keys: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("key"))
        .filter_map(|n| n.text())
        .collect();
    for key in [
        "CFBundleExecutable",
        "CFBundleIdentifier",
        "UILaunchScreen",
        "UISupportedInterfaceOrientations",
        "UIRequiredDeviceCapabilities",
    ] {
        assert!(keys.contains(&key), "Info.plist lacks {key}");
    }
    let spec = read("ios/project.yml");
    for needle in [
        "-lpalpa_app",
        "build-rust.sh",
        "Palpa/Info.plist",
        "liver-coarse.palpa",
    ] {
        assert!(spec.contains(needle), "project.yml lacks {needle}");
    }
    assert!(executable("ios/build-rust.sh"));
    assert!(read("ios/build-rust.sh").contains("--no-default-features"));
    assert!(read("ios/Palpa/main.m").contains("palpa_ios_main()"));
    assert!(read("app/src/platform.rs").contains("pub extern \"C\" fn palpa_ios_main"));
    assert!(repo("ios/Palpa/Assets.xcassets/AppIcon.appiconset/icon-1024.png").exists());
}
