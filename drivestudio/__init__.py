"""The application layer: the `drivestudio` command and the wiring of sim, perception, controller and the
bridge. Domain logic lives in those packages, not here."""
__version__ = "0.1.0"
