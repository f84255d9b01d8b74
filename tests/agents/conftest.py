"""The agent tests share the env tests' fixtures (tiny brush, no-contact plate offset)."""

from tests.envs.conftest import ENV_ID, NO_CONTACT, TINY, make_env  # noqa: F401
