import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from _bootstrap import load_ember  # noqa: E402

load_ember()
