from drivestudio.worlds.highway.plugin import Plugin

__all__ = ["Plugin"]
