"""The devices' emulators: the simulated plant behind the serial bridge's and the CANopen I/O node's
protocols, for benches and tests without hardware. They import the drivers' protocol and sensor
code and ``sim_backend``; the drivers in ``hardware`` never import them (they name them in a
registry, loaded only when a config asks for an in-process emulator)."""
