from drivestudio.worlds.sidewalk.plugin import Plugin

__all__ = ["Plugin"]
