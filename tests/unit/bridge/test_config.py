"""The endpoint's settings: command line over private rosparams over defaults, and every bad value refused by name."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import pytest

from bridge.__main__ import _parser, build_config
from bridge.config import ConfigError, EndpointConfig
from bridge.settings import KINDS, SETTINGS, markdown_table, parse_size

REPO = Path(__file__).resolve().parents[3]


class Params:
    """The rosparams the endpoint node would see (its private names already spelled '~name')."""

    def __init__(self, **values: Any) -> None:
        self.values = {("~" + key if not key.startswith("ROS_") else "/" + key): value for key, value in values.items()}

    def get_param(self, name: str, default: Any) -> Any:
        return self.values.get(name, default)


def config(argv: list[str], environ: dict[str, str] | None = None, **params: Any) -> EndpointConfig:
    return build_config(_parser().parse_args(argv), Params(**params), environ or {})


def test_defaults_are_a_loopback_endpoint_on_unitys_port() -> None:
    defaults = config([])
    assert (defaults.tcp_ip, defaults.tcp_port) == ("127.0.0.1", 10000)
    assert defaults == EndpointConfig()


def test_command_line_beats_rosparam_beats_the_original_endpoints_global_params() -> None:
    assert config([], ROS_IP="10.1.2.3", ROS_TCP_PORT=10001).tcp_port == 10001
    assert config([], tcp_port=10002, ROS_TCP_PORT=10001).tcp_port == 10002
    assert config(["--tcp-port", "10003"], tcp_port=10002).tcp_port == 10003
    assert config([], tcp_ip="0.0.0.0", ROS_IP="10.1.2.3").tcp_ip == "0.0.0.0"


def test_rosparams_of_other_yaml_types_are_converted_when_unambiguous() -> None:
    loaded = config(
        [],
        tcp_port="10004",
        queue_frames=64.0,
        service_timeout=3,
        validate_payloads="False",
        auth_token=1234,
        allow_topics="/a/*, /b",
        deny_topics=["/a/secret"],
    )
    assert (loaded.tcp_port, loaded.client_queue_frames, loaded.service_timeout_s) == (10004, 64, 3.0)
    assert loaded.validate_payloads is False
    assert loaded.auth_token == "1234"
    assert (loaded.allow_topics, loaded.deny_topics) == (("/a/*", "/b"), ("/a/secret",))


def test_which_topics_a_client_behind_gets_only_the_newest_of() -> None:
    defaults = config([])
    assert defaults.latest_only_bytes == 64 * 1024 and not defaults.latest_only("/camera/image")
    chosen = config(["--latest-only", "/camera/*", "--latest-only-bytes", "0"], latest_only_topics="/other")
    assert chosen.latest_only_topics == ("/camera/*",) and chosen.latest_only_bytes == 0
    assert chosen.latest_only("/camera/image") and not chosen.latest_only("/joint_states")
    assert config([], latest_only_topics="/a, /b/*", latest_only_bytes="1000").latest_only("/b/c")
    with pytest.raises(ConfigError, match="latest_only_bytes"):
        EndpointConfig(latest_only_bytes=-1)


def test_the_proxy_secret_comes_from_the_environment_so_that_it_need_not_show_in_ps() -> None:
    environ = {"ROS_TCP_PROXY_SECRET": "from-env"}
    assert config([]).proxy_secret is None  # no proxy can prove itself: X-Forwarded-For is never believed
    assert config([], environ).proxy_secret == "from-env"
    assert config([], environ, proxy_secret="from-param").proxy_secret == "from-env"  # the environment beats rosparams
    assert config(["--proxy-secret", "from-option"], environ).proxy_secret == "from-option"
    assert config([], proxy_secret="from-param").proxy_secret == "from-param"
    assert config([], {"ROS_TCP_PROXY_SECRET": ""}).proxy_secret is None  # empty means unset, as for the token


def test_the_launch_files_empty_token_means_auth_is_off() -> None:
    assert config([], auth_token="").auth_token is None
    assert config(["--no-validate"], validate_payloads=True).validate_payloads is False


@pytest.mark.parametrize(
    ("params", "setting", "fragment"),
    [
        ({"tcp_port": "abc"}, "tcp_port", "'abc' is not a whole number"),
        ({"tcp_port": 10000.5}, "tcp_port", "10000.5 is not a whole number"),
        ({"tcp_port": True}, "tcp_port", "True is not a whole number"),
        ({"ROS_TCP_PORT": "ten"}, "tcp_port", "'ten' is not a whole number"),
        ({"queue_frames": [1]}, "client_queue_frames", "[1] is not a whole number"),
        ({"service_timeout": "soon"}, "service_timeout_s", "'soon' is not a number"),
        ({"validate_payloads": "maybe"}, "validate_payloads", "'maybe' is not true or false"),
        ({"auth_token": ["a"]}, "auth_token", "['a'] is not a string"),
        ({"allow_topics": 5}, "allow_topics", "5 is not a list of patterns"),
        ({"deny_topics": ["/a", {"b": 1}]}, "deny_topics", "{'b': 1} is not a string"),
    ],
)
def test_a_rosparam_of_the_wrong_type_is_named(params: dict[str, Any], setting: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as error:
        config([], **params)
    assert error.value.setting == setting and fragment in error.value.problem


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("tcp_ip", ""),
        ("tcp_port", -1),
        ("tcp_port", 65536),
        ("websocket_port", -1),
        ("websocket_port", "9090"),
        ("websocket_port", 10000),  # the TCP port's
        ("max_payload_bytes", 0),
        ("max_payload_bytes", 2**31),  # Unity's client reads lengths as int32
        ("max_destination_bytes", 0),
        ("client_queue_frames", 0),
        ("client_queue_bytes", 0),
        ("client_call_workers", 0),
        ("client_max_pending_calls", 0),
        ("service_timeout_s", 0.0),
        ("service_timeout_s", -3.0),
        ("service_timeout_s", math.nan),
        ("service_timeout_s", math.inf),
        ("publisher_grace_s", -1.0),
        ("publisher_grace_s", math.nan),
        ("publisher_grace_s", True),
        ("websocket_origins", ("",)),
        ("trusted_proxies", ("localhost",)),  # an address, not a name that could resolve to anything
        ("trusted_proxies", ("127.0.0.1", "10.0.0.0/8")),
    ],
)
def test_a_value_the_endpoint_cannot_serve_with_is_refused_before_it_starts(field: str, value: Any) -> None:
    with pytest.raises(ConfigError) as error:
        EndpointConfig(**{field: value})
    shown = repr(value[-1]) if isinstance(value, tuple) else repr(value)
    assert error.value.setting == field and shown in error.value.problem


def test_the_edges_of_each_range_are_accepted() -> None:
    EndpointConfig(tcp_port=0, max_payload_bytes=1, client_queue_frames=1, service_timeout_s=1e-3, publisher_grace_s=0)
    EndpointConfig(tcp_port=65535, max_payload_bytes=2**31 - 1)


def test_the_websocket_port_is_off_unless_given_and_zero_means_any_free_port() -> None:
    assert config([]).websocket_port is None
    assert config([], websocket_port=9090).websocket_port == 9090
    assert config(["--websocket-port", "0"], websocket_port=9090).websocket_port == 0
    assert EndpointConfig(tcp_port=0, websocket_port=0).websocket_port == 0  # two free ports, both picked at bind


def test_every_setting_is_declared_once_in_the_table() -> None:
    fields = [field.name for field in dataclasses.fields(EndpointConfig)]
    assert sorted(setting.name for setting in SETTINGS) == sorted(fields)
    for attribute in ("option", "param"):
        spelled = [getattr(setting, attribute) for setting in SETTINGS]
        assert len(set(spelled)) == len(spelled), f"two settings share an {attribute}"
    assert all(setting.kind in KINDS for setting in SETTINGS)


def test_help_shows_sizes_as_sizes_and_every_settings_rosparam_and_default() -> None:
    shown = " ".join(_parser().format_help().split())  # argparse wraps lines
    assert "e+" not in shown and "default 256 MiB" in shown and "default 64 MiB" in shown
    assert "default 4 MiB" in shown and "default 64 KiB" in shown and "default 30 s" in shown
    for setting in SETTINGS:
        assert setting.option in shown and f"rosparam {setting.param};" in shown


def test_sizes_are_read_in_bytes_or_binary_units() -> None:
    assert parse_size("s", "1048576") == parse_size("s", "1MiB") == parse_size("s", " 1 mib ") == 2**20
    assert parse_size("s", "1.5 KiB") == 1536 and parse_size("s", "2GiB") == 2**31
    assert config(["--max-payload-bytes", "128MiB"], queue_bytes="8 MiB").client_queue_bytes == 8 * 2**20
    assert config(["--max-payload-bytes", "128MiB"]).max_payload_bytes == 128 * 2**20
    for text, problem in (("12 MB", "is not a size"), ("0.3 KiB", "not a whole number of bytes"), ("", "not a size")):
        with pytest.raises(ConfigError, match=problem):
            parse_size("s", text)
    with pytest.raises(ConfigError, match="from 1 to 2147483647, got 2147483648"):
        config(["--max-payload-bytes", "2GiB"])


def test_a_bad_value_on_the_command_line_is_named_like_a_bad_rosparam() -> None:
    with pytest.raises(ConfigError) as error:
        config(["--tcp-port", "abc"])
    assert (error.value.setting, error.value.problem) == ("tcp_port", "'abc' is not a whole number")


def test_the_readme_table_is_the_settings_table() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    start = readme.index("<!-- settings: python -m bridge.config -->\n")
    copy = readme[readme.index("\n", start) + 1 : readme.index("<!-- /settings -->")]
    assert copy.strip() == markdown_table(EndpointConfig()), "run `python -m bridge.config` and paste its table"


def test_the_launch_files_parameters_are_settings_of_their_kind() -> None:
    by_param = {setting.param.lstrip("~"): setting for setting in SETTINGS}
    launch = ElementTree.parse(REPO / "catkin_ws/src/ros_tcp_endpoint/launch/endpoint.launch").getroot()
    params = launch.findall("./node/param")
    assert params
    kinds = {"string": ("address", "text", "patterns", "ips"), "int": ("port", "count", "bytes"), "bool": ("switch",)}
    for param in params:
        setting = by_param[param.get("name")]  # a KeyError is a parameter the endpoint does not read
        assert setting.kind in kinds.get(param.get("type"), ("seconds",)), param.get("name")
