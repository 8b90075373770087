"""README cannot drift: every fenced block of README.md preceded by the line
`<!-- checked -->` is a shell session (`$ command` lines, each followed by the
output README shows). The test runs each command with the built `sphnl` and
`sphnl_bench` in a scratch folder holding the input files README names, and
compares the shape of the output with README's: the lines README shows must
be the first lines of the real output (stdout and stderr together), numbers
aside (timings and rates differ between machines), runs of identical-shape
progress lines counting as one. `make test` sets SPHNL_BUILD_DIR; without it the test is
skipped."""
import os
import re
import subprocess
import tempfile
import unittest
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
MARK = "<!-- checked -->"
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def checked_blocks(text):
    """(line number, [(command, [expected output lines])]) of every checked block."""
    lines = text.splitlines()
    blocks = []
    for i, line in enumerate(lines):
        if line.strip() != MARK:
            continue
        if i + 1 >= len(lines) or not lines[i + 1].startswith("```"):
            raise AssertionError(f"README.md:{i + 1}: {MARK} must be followed by a fenced block")
        session, j = [], i + 2
        while j < len(lines) and not lines[j].startswith("```"):
            if lines[j].startswith("$ "):
                session.append((lines[j][2:], []))
            elif session:
                session[-1][1].append(lines[j])
            else:
                raise AssertionError(f"README.md:{j + 1}: a checked block must start with a `$ command` line")
            j += 1
        blocks.append((i + 2, session))
    return blocks


def shape(lines):
    """Lines with every number replaced by #, consecutive duplicates merged."""
    out = []
    for line in lines:
        s = NUMBER.sub("#", line.rstrip())
        if not out or out[-1] != s:
            out.append(s)
    return out


def write_inputs(folder):
    """The input files README's examples name."""
    with open(folder / "lattice20.csv", "w", encoding="utf-8") as f:
        f.write("x,y,z\n")
        for k in range(20):
            for j in range(20):
                for i in range(20):
                    f.write(f"{i},{j},{k}\n")
    (folder / "bad.csv").write_text("x,y,z\n1,2\n", encoding="utf-8")
    # experiments/fig06.json with its tiny sweep in the axis names used before the config's keys
    lines = (ROOT / "experiments" / "fig06.json").read_text(encoding="utf-8").splitlines(keepends=True)
    tiny = next(i for i, line in enumerate(lines) if line.lstrip().startswith('"tiny"'))
    for new, old in (("particles", "n"), ("cell_order", "order"), ("list_steps", "ns")):
        lines[tiny] = lines[tiny].replace(f'"{new}":', f'"{old}":')
    (folder / "old.json").write_text("".join(lines), encoding="utf-8")


class ShapeTest(unittest.TestCase):
    def test_shape_ignores_numbers_and_repeated_progress_lines(self):
        self.assertEqual(shape(["step 1  t = 0.0016 s", "step 27  t = 0.04 s", "done 3.5e+07"]),
                         ["step #  t = # s", "done #"])

    def test_blocks_are_found_with_their_commands(self):
        text = "x\n<!-- checked -->\n```\n$ sphnl a\nout 1\n$ head f\nline\n```\n"
        self.assertEqual(checked_blocks(text), [(3, [("sphnl a", ["out 1"]), ("head f", ["line"])])])


@unittest.skipUnless(os.environ.get("SPHNL_BUILD_DIR"), "SPHNL_BUILD_DIR not set (make test sets it)")
class ReadmeExamples(unittest.TestCase):
    def test_every_checked_example_gives_the_output_readme_shows(self):
        build = Path(os.environ["SPHNL_BUILD_DIR"]).resolve()
        self.assertTrue((build / "sphnl").is_file(), f"{build / 'sphnl'} is missing: build it with `make build`")
        blocks = checked_blocks(README.read_text(encoding="utf-8"))
        self.assertGreaterEqual(len(blocks), 3, "README.md lost its checked examples")
        env = dict(os.environ, PATH=os.pathsep.join([str(build), str(build / "benchmarks"),
                                                     os.environ.get("PATH", "")]))
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            write_inputs(folder)
            for line_no, session in blocks:
                for command, expected in session:
                    run = subprocess.run(["bash", "-c", command], cwd=folder, env=env, stdout=subprocess.PIPE,
                                         stderr=subprocess.STDOUT, text=True, timeout=300)
                    want, got = shape(expected), shape(run.stdout.splitlines())
                    self.assertEqual(got[:len(want)], want,
                                     f"README.md:{line_no}: `{command}` (exit {run.returncode}) printed\n"
                                     f"{run.stdout[:3000]}\nwhich does not start like README's example; "
                                     "update README.md with the real output")


if __name__ == "__main__":
    unittest.main()
