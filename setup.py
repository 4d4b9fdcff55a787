"""The package's compiled part: the bus's cycle transactions (whexar/bus/_wire.c).

Everything else is in pyproject.toml. The extension is optional: where it cannot be
built (no C compiler, no Python headers), the install goes on and whexar uses
dynamixel-sdk's pure-Python path, with the same results (whexar.bus.wire).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "whexar.bus._wire",
            ["whexar/bus/_wire.c"],
            optional=True,
            extra_compile_args=["-O2", "-Wall", "-Wextra", "-Wno-unused-parameter"],
        )
    ]
)
