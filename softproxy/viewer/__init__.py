"""The viewer: draws the MuJoCo scene, every finger's proxy, device ghost, spring, force and torsion.

It never runs inside the servo loop. The servo side is a cheap publisher
(`softproxy.viewer.state.StatePublisher`, an `on_tick` callable) that every N ticks copies
the state into a shared-memory block under a seqlock; the viewer is its own process
(`python -m softproxy.viewer SCENE --shm NAME`) that opens the model itself and reads that
block at display rate. A slow, frozen or closed window therefore cannot delay a tick.

Modules (only `render`, `offscreen` and `window` import GL; importing this package does not):

- `state`     shared-memory layout, seqlock publisher (servo side) and reader, command slot
- `meshes`    triangle meshes of the MuJoCo geom types (numpy)
- `camera`    orbit camera, projection, framing (numpy)
- `render`    `SceneRenderer`: moderngl drawing of a state frame, text overlay
- `offscreen` EGL standalone context + framebuffer: snapshots and video frames
- `window`    glfw window: mouse orbit/zoom/pan, keys
- `servo_watch` is the servo process still there (the viewer closes when it is gone)
- `launch`    start the viewer process (isolated from the working directory); every wait bounded
- `attach`    what `softproxy run` hangs on a run: window, snapshot, video
"""
