"""python -m roadx_ti.bench ... (the same as python -m roadx_ti bench ...)"""
import argparse

from roadx_ti.bench.command import add_arguments, main

_p = argparse.ArgumentParser(prog="python -m roadx_ti.bench")
add_arguments(_p)
raise SystemExit(main(_p.parse_args()))
