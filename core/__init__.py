"""The bottom of the house: what every package shares and nothing depends on it but numpy.

  declaration  WorldDeclaration: a world's cameras, labels, truth record, action, modes and data moment
  worlds/      the declared worlds (highway, sidewalk) and each one's shared vocabulary (indicator names,
               inactive values, normalisation, the action, the car's constants)
  inputs       the one bounded, strict reader of JSON input files and the checks of their fields
  files        safe output writing: checks before work, atomic replacement, stale temporaries reclaimed
  signals      SIGTERM and SIGHUP unwind like Ctrl-C, so that every `finally` runs
  processes    whether another process is still there

sim, perception, controller and shm_bridge import from here and not from each other (docs/architecture.md).
"""
