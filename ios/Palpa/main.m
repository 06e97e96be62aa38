// The iOS entry point: everything else is palpa-app (Rust). palpa_ios_main runs
// winit's event loop, which calls UIApplicationMain and never returns.
extern void palpa_ios_main(void);

int main(int argc, char *argv[]) {
    (void)argc;
    (void)argv;
    palpa_ios_main();
    return 0;
}
