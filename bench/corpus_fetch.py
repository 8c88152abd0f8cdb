"""Fetch the public programs of bench/corpus/manifest.toml into a directory outside the repository.

    python bench/corpus_fetch.py ~/nckemu-corpus
    python bench/corpus_fetch.py ~/nckemu-corpus --source '/mirrors/{owner}+{name}/repo'

Each repository is fetched at its manifest commit (one commit, no history) into DIR/<owner>+<name>/;
one already there at that commit is kept. The programs stay there: their licences are their
authors', and nothing of them belongs in nckemu's repository. This needs the network (GitHub), which
CI does not have: the corpus is for developers, and the slow test that runs it skips without it.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tomllib
from pathlib import Path

MANIFEST = Path(__file__).with_name("corpus") / "manifest.toml"
GITHUB = "https://github.com/{owner}/{name}.git"


def load_manifest(path: Path = MANIFEST) -> dict:
    with path.open("rb") as handle:
        return tomllib.load(handle)


def repository_dir(root: Path, repo: str) -> Path:
    owner, name = repo.split("/", 1)
    return root / f"{owner}+{name}"


def _git(*args: str, cwd: Path) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def fetch_repository(root: Path, repo: str, commit: str, source: str) -> Path:
    target = repository_dir(root, repo)
    if (target / ".git").is_dir():
        try:
            if _git("rev-parse", "HEAD", cwd=target) == commit:
                return target
        except subprocess.CalledProcessError:
            pass
    target.mkdir(parents=True, exist_ok=True)
    owner, name = repo.split("/", 1)
    if not (target / ".git").is_dir():
        _git("init", "-q", cwd=target)
    _git("fetch", "-q", "--depth", "1", source.format(owner=owner, name=name), commit, cwd=target)
    _git("checkout", "-q", "--force", commit, cwd=target)
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("directory", type=Path, help="where the repositories go (outside nckemu's checkout)")
    parser.add_argument("--source", default=GITHUB,
                        help="URL or path template with {owner} and {name} (default: GitHub)")
    args = parser.parse_args(argv)
    manifest = load_manifest()
    failed = 0
    for entry in manifest["repository"]:
        try:
            path = fetch_repository(args.directory, entry["repo"], entry["commit"], args.source)
            print(f"{entry['repo']} @ {entry['commit'][:10]}: {path}")
        except subprocess.CalledProcessError as exc:
            failed += 1
            print(f"{entry['repo']}: not fetched ({exc.stderr.strip() or exc})", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
