"""What the studio's browser tests share: one headless Chromium per test module."""
import pytest

from tests.studio.helpers import browser, close_browser


@pytest.fixture(scope="module")
def page():
    driver = browser()
    yield driver
    close_browser(driver)
