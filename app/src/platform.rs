//! Platform entry points other than the desktop's `main.rs`. Only this module knows
//! about them; rendering, input and loops are the same on every platform.
//!
//! - Android: `android_main`, called by android-activity (through winit's
//!   `android-native-activity` feature) when the activity starts; the cdylib is the
//!   app's `libpalpa_app.so`. The built-in scene is compiled in, so no asset access is
//!   needed.
//! - iOS: the staticlib/cdylib's `palpa_ios_main`, called from the Xcode project's
//!   `main` (packaging issue), which runs the same event loop.

/// Android entry point.
#[cfg(target_os = "android")]
#[unsafe(no_mangle)]
#[allow(unsafe_code)] // The symbol name android-activity looks for; no unsafe code inside.
fn android_main(app: winit::platform::android::activity::AndroidApp) {
    use tracing_subscriber::Layer;
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    use winit::platform::android::EventLoopBuilderExtAndroid;
    // Errors and warnings go to logcat (`adb logcat -s palpa`): a device has no
    // terminal. A second start of the activity in the same process keeps the first
    // subscriber.
    let _ = tracing_subscriber::registry()
        .with(
            paranoid_android::layer("palpa")
                .with_filter(tracing_subscriber::filter::LevelFilter::INFO),
        )
        .try_init();
    let event_loop = match winit::event_loop::EventLoop::builder()
        .with_android_app(app)
        .build()
    {
        Ok(l) => l,
        Err(e) => {
            tracing::error!("cannot start the event loop: {e}");
            return;
        }
    };
    if let Err(e) = crate::window::run_on(event_loop, "liver") {
        tracing::error!("{e:#}");
    }
}

/// iOS entry point (called from the Xcode project's `main`).
#[cfg(target_os = "ios")]
#[unsafe(no_mangle)]
#[allow(unsafe_code)] // An exported C symbol; no unsafe code inside.
pub extern "C" fn palpa_ios_main() {
    if let Err(e) = crate::window::run("liver") {
        tracing::error!("{e:#}");
    }
}
