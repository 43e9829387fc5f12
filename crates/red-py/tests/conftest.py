import os
import pathlib
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
DEMO = ROOT / "data" / "drive-scripted-expert.json"


def red_cli() -> list:
    """The red-cli command: RED_CLI if set, else a built binary of the
    workspace (release, then debug), else `cargo run`."""
    if os.environ.get("RED_CLI"):
        return [os.environ["RED_CLI"]]
    for profile in ("release", "debug"):
        exe = ROOT / "target" / profile / "red-cli"
        if exe.exists():
            return [str(exe)]
    if shutil.which("cargo"):
        return ["cargo", "run", "-q", "--release", "-p", "red-cli", "--"]
    pytest.skip("no red-cli binary and no cargo")


def run_cli(*args: str) -> str:
    out = subprocess.run(red_cli() + list(args), cwd=ROOT, check=True, capture_output=True, text=True)
    return out.stdout


@pytest.fixture(scope="session")
def demo_path():
    return DEMO


@pytest.fixture(scope="session")
def demos():
    import red

    return red.read_demos(DEMO)
