"""Device implementations (simulated, HID, replay) of the protocol in `softproxy.device`."""
