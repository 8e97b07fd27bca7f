"""The app's panels. Each is a widget with ``refresh_view(engine, now)``, which the app calls
about ten times a second while the panel is visible: panels copy plain values out of the role
cores and never do I/O."""
