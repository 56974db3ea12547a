"""The VR condition: a WebXR page for a browser headset, its server and its certificate (docs/study.md)."""
