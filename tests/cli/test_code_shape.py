"""The house rule of issue 12: no function in native/ or addon/ over 120
lines, so the next engineer can hold each one in their head. Measured by
tools/function_lengths.py (which also lists the ones over 60)."""
import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MAX_LINES = 120


def load_tool():
    spec = importlib.util.spec_from_file_location("function_lengths", REPO / "tools" / "function_lengths.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_measure_finds_cpp_and_python_functions_of_known_length(tmp_path):
    tool = load_tool()
    (tmp_path / "native").mkdir()
    (tmp_path / "addon").mkdir()
    body = "\n".join(f"    x += {i};  // {{ not a brace" for i in range(10))
    (tmp_path / "native" / "a.cpp").write_text(
        'int f(int x) {\n' + body + '\n    if (x) { x = 1; }\n    const char* s = "}";\n    return x;\n}\n'
        'struct S {\n    int g() const { return 1; }\n};\n')
    (tmp_path / "addon" / "b.py").write_text("def h():\n    a = 1\n    return a\n")
    found = {name: length for length, _, _, name in tool.functions(tmp_path)}
    assert found == {"f": 15, "g": 1, "h": 3}


def test_no_function_over_120_lines():
    tool = load_tool()
    long = [f"{path.relative_to(REPO)}:{line} {name} ({length} lines)"
            for length, path, line, name in tool.functions() if length > MAX_LINES]
    assert not long, "split these into named steps: " + "; ".join(long)
