#!/usr/bin/env python3
"""Docs that cannot drift: every `echoservo ...` command line in README.md and docs/*.md
is parsed by the real CLI.

    docs_commands_test.py ECHOSERVO [REPO_ROOT] [--list]

It collects the command lines of fenced code blocks (backslash continuations joined, `$ `
prompts, `&&`/`;`/`&` chains, `xvfb-run -a` and `# comments` handled) and of inline code
spans, and runs them all through one `ECHOSERVO_PARSE_ONLY=batch echoservo` process (apps/cli.cc):
CLI11 parses and validates each line exactly as for a real run, but no command runs.

* example: a line without grammar. Placeholders (RUN, DIR, FILE, N, S, MM, HOST:PORT,
  `<...>`, ...) get sample values; it must parse (exit 0, the command it names reached).
  An inline span that only lacks a required argument (`echoservo report --em` in prose)
  counts as a fragment: its subcommand and flags must exist.
* synopsis: a line with `[...]`, `(...)`, `|` alternatives or `...`. Every `--flag` it
  names must exist for its subcommand (from `echoservo <sub> --help`), and two instances
  must parse: the minimal one (optional groups left out) and the maximal one (all optional
  groups in; the first of spaced `a | b` branches, the last of `a|b` words).
* name: `echoservo sim track` alone; the subcommand must exist.
* reference: an inline span that names a command and flags without `echoservo`
  (`track --sim`, `demo --save-volumes`); the flags must exist for that command.

Every path under data/ that a line names must exist in the repository. Python 3 standard
library only; a few seconds (four echoservo processes: three for the --help pages, one
for all the lines).
"""

import os
import re
import shlex
import subprocess
import sys
import tempfile

FENCE = re.compile(r"^\s*(```|~~~)")
# A command starts a line or a shell segment, after an optional prompt or wrapper.
COMMAND = re.compile(
    r"^(?:\$\s+|next:\s+)?(?:[A-Z_][A-Z0-9_]*=\S*\s+)*(?:xvfb-run\s+-a\s+|time\s+)?"
    r"(?:\./)?(?:build[\w-]*/bin/)?echoservo(?=\s|$)(?P<args>.*)$",
    re.S,
)
GRAMMAR = re.compile(r"[\[\]()|]|\.\.\.|…")
# Sample values for the placeholders the docs use. Whole-token placeholders first.
TOKEN_VALUES = {
    "N": "3",
    "S": "5",
    "MM": "6",
    "DB": "40",
    "HZ": "25",
    "BPM": "60",
    "C": "0.5",
    "M": "1,0,0,0,0,1,0,0,0,0,1,0",
    "SPEC": "seed",
    "NAME": "sample",
    "P": "18944",
    "IP": "127.0.0.1",
    "HOST:PORT": "127.0.0.1:18944",
    "A,B": "water_tank,spine_phantom",  # bench detect --classes A,B
    "FILE": "README.md",  # an existing file, for CLI::ExistingFile (bench detect --spine)
}
PATH_WORDS = re.compile(r"\b(RUN2?|DIR|LOG|FILE|TRACE|DATASET|VOLUME|SEQUENCE)\b")
MISSING_ONLY = re.compile(
    r"is required|required .* missing|requires at least|A subcommand is required"
)


def docs(root):
    names = ["README.md"] + sorted(
        os.path.join("docs", f) for f in os.listdir(os.path.join(root, "docs")) if f.endswith(".md")
    )
    for name in names:
        with open(os.path.join(root, name), encoding="utf-8") as f:
            yield name, f.read().split("\n")


def segments(text):
    """Shell segments of one logical line: split at && || ; & and cut # comments."""
    text = re.sub(r"(^|\s)#.*$", "", text)
    for part in re.split(r"\s(?:&&|\|\||;|&)\s|[;&]\s*$", text):
        yield part.strip()


def collect(root):
    """(file, line, kind, args) for every echoservo command line; kind: fenced | inline."""
    found = []
    for name, lines in docs(root):
        in_fence = False
        prose = []
        i = 0
        while i < len(lines):
            line = lines[i]
            if FENCE.match(line):
                in_fence = not in_fence
                prose.append("")
                i += 1
                continue
            if not in_fence:
                prose.append(line)
                i += 1
                continue
            start = i
            logical = line
            while logical.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                prose.append("")
                logical = logical.rstrip()[:-1] + " " + lines[i].strip()
            prose.append("")
            i += 1
            for seg in segments(logical.strip()):
                m = COMMAND.match(seg)
                if m:
                    found.append((name, start + 1, "fenced", m.group("args").strip()))
        text = "\n".join(prose)
        for m in re.finditer(r"(`+)(.+?)\1", text, re.S):
            span = m.group(2).replace("\\|", "|").replace("\n", " ").strip()
            line = text.count("\n", 0, m.start()) + 1
            for seg in segments(span):
                c = COMMAND.match(seg)
                if c:
                    found.append((name, line, "inline", c.group("args").strip()))
    return found


def references(root, commands):
    """(file, line, span) for inline spans that name a command without `echoservo` and
    some of its flags, e.g. `track --sim` or `demo --save-volumes`."""
    for name, lines in docs(root):
        prose, in_fence = [], False
        for line in lines:
            if FENCE.match(line):
                in_fence = not in_fence
            prose.append("" if in_fence or FENCE.match(line) else line)
        text = "\n".join(prose)
        for m in re.finditer(r"(`+)(.+?)\1", text, re.S):
            span = m.group(2).replace("\\|", "|").replace("\n", " ").strip()
            words = span.split()
            if len(words) >= 2 and words[0] in commands and "--" in span:
                yield name, text.count("\n", 0, m.start()) + 1, span


def substitute(args):
    """Sample values for placeholders; `...` dropped. Returns the argument list."""
    args = re.sub(r"<[^>]*>", "1", args).replace("…", " ").replace("...", " ")
    out = []
    for tok in shlex.split(args):
        if tok in TOKEN_VALUES:
            out.append(TOKEN_VALUES[tok])
            continue
        tok = re.sub(r"(?<=:)N\b", "3", tok)  # heartbeat:N
        out.append(PATH_WORDS.sub(lambda w: "sample_" + w.group(1).lower(), tok))
    return out


def grammar_tree(text):
    """Parse [optional], (group) and spaced `|` into nested branches."""
    tokens = re.findall(r"\[|\]|\(|\)|\||[^\[\]()|]+", text)
    pos = 0

    def alternatives(closing):
        nonlocal pos
        branches = [[]]
        while pos < len(tokens):
            tok = tokens[pos]
            pos += 1
            if tok == closing:
                return branches
            if tok == "|":
                branches.append([])
            elif tok in "[(":
                inner = alternatives("]" if tok == "[" else ")")
                branches[-1].append(("opt" if tok == "[" else "grp", inner))
            else:
                branches[-1].append(("text", tok))
        return branches

    return alternatives(None)


def instance(branches, maximal):
    def render(nodes):
        out = ""
        for kind, value in nodes:
            if kind == "text":
                out += value
            elif kind == "grp" or maximal:
                out += render(value[0])
        return out

    return render(branches[0])


def synopsis_instances(args):
    # Word-level alternatives (`auto|plus`, `compare|diagnose`, `--sim|--connect HOST:PORT`):
    # the last one; spaced `a | b` and bracketed groups are handled by the grammar.
    words = re.sub(r"[^\s\[\]()|]+(?:\|[^\s\[\]()|]+)+", lambda m: m.group(0).split("|")[-1], args)
    tree = grammar_tree(words)
    return {instance(tree, False), instance(tree, True)}


class Cli:
    def __init__(self, exe, cwd):
        self.exe = exe
        self.cwd = cwd

    def batch(self, lines):
        """Parse-only runs in one process: [(rc, stdout, stderr)] per argument list."""
        for args in lines:
            for a in args:
                if "\t" in a or "\n" in a:
                    raise ValueError("argument with a tab or newline: %r" % a)
        env = dict(os.environ, ECHOSERVO_PARSE_ONLY="batch")
        p = subprocess.run(
            [self.exe],
            input="".join("\t".join(a) + "\n" for a in lines),
            capture_output=True,
            text=True,
            env=env,
            cwd=self.cwd,
            timeout=120,
        )
        if p.returncode != 0:
            raise RuntimeError("echoservo batch parse failed: rc %d\n%s" % (p.returncode, p.stderr))
        marker = re.compile(r"^--- rc (-?\d+)$", re.M)
        outs = marker.split(p.stdout)
        errs = marker.split(p.stderr)
        if len(outs) != 2 * len(lines) + 1 or len(errs) != 2 * len(lines) + 1:
            raise RuntimeError(
                "echoservo batch parse: %d results for %d lines" % (len(outs) // 2, len(lines))
            )
        return [
            (int(outs[2 * k + 1]), outs[2 * k].strip(), errs[2 * k].strip())
            for k in range(len(lines))
        ]


def help_tree(cli):
    """{subcommand path tuple: set of option names} from the --help pages."""
    tree = {}
    pending = [()]
    while pending:
        paths = pending
        pending = []
        for path, (rc, out, err) in zip(paths, cli.batch([list(p) + ["--help"] for p in paths])):
            if rc != 0:
                raise RuntimeError("echoservo %s --help: rc %d %s" % (" ".join(path), rc, err))
            options = set()
            section = ""
            for line in out.split("\n"):
                if line and not line.startswith(" "):
                    section = line.strip()
                    continue
                m = re.match(r"^ {2}(\S+)", line)
                if not m:
                    continue
                if section.startswith("Subcommands"):
                    pending.append(path + (m.group(1),))
                elif m.group(1).startswith("-"):
                    options.update(n for n in m.group(1).split(",") if n.startswith("-"))
            tree[path] = options
    return tree


def command_paths(tree, words):
    """Subcommand paths a line names (several for `compare|diagnose`); [] if unknown."""
    paths = [()]
    for w in words:
        w = w.strip("[]()")
        nxt = [p + (alt,) for p in paths for alt in w.split("|") if p + (alt,) in tree]
        if not nxt:
            break
        paths = nxt
    return paths


def data_paths(args):
    for tok in re.split(r"[\s,=@\[\]()|]+", args):
        if tok.startswith("data/"):
            yield tok


def self_check(cli):
    """The parse-only mode runs no command and still rejects what the CLI rejects."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "motion.csv")
        (rc, stdout, err), (bad_rc, _, _) = cli.batch(
            [["sim", "motion", "--out", out], ["demo", "--no-such-flag"]]
        )
        if rc != 0 or stdout != "parse only: echoservo sim motion" or os.path.exists(out):
            raise RuntimeError("ECHOSERVO_PARSE_ONLY ran a command: %d %r %r" % (rc, stdout, err))
        if bad_rc == 0:
            raise RuntimeError("ECHOSERVO_PARSE_ONLY accepted an unknown flag")


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 2
    exe = os.path.abspath(argv[1])
    rest = [a for a in argv[2:] if a != "--list"]
    root = os.path.abspath(rest[0] if rest else os.path.join(os.path.dirname(__file__), "..", ".."))
    cli = Cli(exe, root)
    self_check(cli)
    tree = help_tree(cli)
    lines = collect(root)
    failures = []
    counts = {"example": 0, "synopsis": 0, "fragment": 0, "name": 0}
    runs = []  # (index in classified, entry, label, args)
    classified = []
    for entry in lines:
        name, line, kind, args = entry
        where = "%s:%d" % (name, line)
        if args in ("...", "…"):  # `echoservo ...`: the program itself
            args = ""
        for p in data_paths(args):
            if not os.path.exists(os.path.join(root, p)):
                failures.append("%s: `echoservo %s`: %s does not exist" % (where, args, p))
        words = args.split()
        paths = command_paths(tree, words)
        depth = len(paths[0])
        if depth == 0 and words and not words[0].startswith("-"):
            failures.append("%s: `echoservo %s`: no such command" % (where, args))
            continue
        if GRAMMAR.search(args):
            cls = "synopsis"
            flags = set(re.findall(r"(?<![\w-])--[A-Za-z0-9][\w-]*", args))
            for p in paths:
                for f in sorted(flags - tree[p]):
                    failures.append(
                        "%s: `echoservo %s`: `echoservo %s` has no %s"
                        % (where, args, " ".join(p), f)
                    )
            for inst in sorted(synopsis_instances(args)):
                label = "instance `echoservo %s`" % " ".join(substitute(inst))
                runs.append((len(classified), entry, label, substitute(inst)))
        elif depth == len(words):
            cls = "name"
        else:
            cls = "example"
            runs.append((len(classified), entry, "", substitute(args)))
        counts[cls] += 1
        classified.append([where, cls, kind, args])
    # `track --sim` in prose: the flags must exist.
    n_references = 0
    for name, line, span in references(root, {p[0] for p in tree if p}):
        n_references += 1
        flags = set(re.findall(r"(?<![\w-])--[A-Za-z0-9][\w-]*", span))
        for p in command_paths(tree, span.split()):
            for f in sorted(flags - tree[p]):
                failures.append(
                    "%s:%d: `%s`: `echoservo %s` has no %s" % (name, line, span, " ".join(p), f)
                )
    results = cli.batch([r[3] for r in runs])
    for (index, entry, label, args), (rc, out, err) in zip(runs, results):
        name, line, kind, text = entry
        where = "%s:%d" % (name, line)
        if rc == 0 and ("parse only: echoservo" in out or "--help" in args):
            continue
        msg = (err or out).split("\n")[0]
        if not label and kind == "inline" and MISSING_ONLY.search(msg):
            # A command named in prose with some of its flags: check they exist.
            paths = command_paths(tree, text.split())
            flags = set(re.findall(r"(?<![\w-])--[A-Za-z0-9][\w-]*", text))
            missing = [f for p in paths for f in sorted(flags - tree[p])]
            if not missing:
                classified[index][1] = "fragment"
                continue
            msg = "no %s" % ", ".join(missing)
        label = (" " + label) if label else ""
        failures.append("%s: `echoservo %s`%s: rc %d: %s" % (where, text, label, rc, msg))
    counts["fragment"] = sum(1 for c in classified if c[1] == "fragment")
    counts["example"] -= counts["fragment"]
    if "--list" in argv:
        for where, cls, kind, args in classified:
            print("%-10s %-7s %s: echoservo %s" % (cls, kind, where, args))
    print(
        "docs_commands: %d command lines in README.md and docs/*.md: %d examples, "
        "%d synopses (flags checked, %d instances parsed), %d fragments, %d command names; "
        "%d references without `echoservo` (flags checked); %d failures"
        % (
            len(classified),
            counts["example"],
            counts["synopsis"],
            sum(1 for r in runs if r[2]),
            counts["fragment"],
            counts["name"],
            n_references,
            len(failures),
        )
    )
    for f in failures:
        print("FAIL " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
