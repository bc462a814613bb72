#!/usr/bin/env python3
"""Runs every command line of the README and of the docs, as a new user would, and fails when one fails.

usage: readme_commands_test.py --hmap BIN --source REPO --data DATA_DIR [--only SUBSTRING]

Which lines run (the rule README.md states):
  - README.md: every line of every ```sh block;
  - docs/*.md: every line of the ```sh runnable blocks (other blocks are examples with placeholders);
  - a line that starts with `make` is not run: the test runs from the build `make` made;
  - lines ending in `\\` are joined with the next; `#` lines and blank lines are skipped.
Each line runs in bash (`set -euo pipefail`) in a scratch folder laid out as a fresh checkout:
REPO_SCRATCH/ (the working folder, with tests/ linked to the source's) next to shared/data (linked to
DATA_DIR), with `hmap` on PATH. Lines run in the order of the files (README first), so a line may
use what an earlier one wrote. A few commands are long jobs (minutes); the test runs them on their
first scans by appending the arguments of SHORTENED below. A SHORTENED entry that matches no line
fails the test, so the table cannot outlive the README.

Exit 0 when every line succeeds, 1 otherwise (each failure listed with its output), 77 (skipped)
when DATA_DIR does not exist.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

# Command prefix (after whitespace is normalised) -> arguments appended by the test, for the long jobs.
SHORTENED = {
    'hmap simulate --scene city': '--frames 20',
    'hmap map --bag out/bag/balm_os0.bag': '--scans 10',
    'hmap slam --kitti ../shared/data/kitti_hdl64_seq16': '--scans 4',
    'hmap compare --kitti ../shared/data/balm_os0': '--scans 4',
    'hmap compare --kitti ../shared/data/kitti_hdl64_seq16': '--scans 4',
    'hmap bench --kitti ../shared/data/kitti_hdl64_seq16': '--scans 4 --repeat 1',
}


def command_lines(path, runnable_only):
    """(line number, command) of the runnable lines of one Markdown file."""
    lines = open(path, encoding='utf-8').read().split('\n')
    commands = []
    in_block = False
    run_block = False
    pending = None
    for number, line in enumerate(lines, start=1):
        fence = re.match(r'^\s*```(.*)$', line)
        if fence:
            if not in_block:
                info = fence.group(1).split()
                in_block = True
                run_block = bool(info) and info[0] == 'sh' and (not runnable_only or 'runnable' in info[1:])
            else:
                in_block = False
            continue
        if not (in_block and run_block):
            continue
        text = line.strip()
        if pending is not None:
            pending = (pending[0], pending[1] + ' ' + text.rstrip('\\').strip())
            if not text.endswith('\\'):
                commands.append(pending)
                pending = None
            continue
        if not text or text.startswith('#'):
            continue
        if text.endswith('\\'):
            pending = (number, text.rstrip('\\').strip())
            continue
        commands.append((number, text))
    return commands


def split_comment(command):
    """The command without a trailing `# comment` (a # that starts a word outside quotes)."""
    quote = None
    for i, c in enumerate(command):
        if quote:
            if c == quote:
                quote = None
        elif c in '\'"':
            quote = c
        elif c == '#' and (i == 0 or command[i - 1].isspace()):
            return command[:i].rstrip()
    return command


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument('--hmap', required=True)
    parser.add_argument('--source', required=True)
    parser.add_argument('--data', required=True)
    parser.add_argument('--only', default='', help='run only the lines containing this text')
    parser.add_argument('--keep', action='store_true', help='keep the scratch folder')
    args = parser.parse_args()
    if not os.path.isdir(args.data):
        print(f'skipped: the data folder {args.data} does not exist (set HMAP_DATA_DIR)')
        return 77

    files = [('README.md', False)]
    docs = os.path.join(args.source, 'docs')
    files += [(os.path.join('docs', name), True) for name in sorted(os.listdir(docs)) if name.endswith('.md')]
    commands = []
    for name, runnable_only in files:
        for number, line in command_lines(os.path.join(args.source, name), runnable_only):
            commands.append((f'{name}:{number}', split_comment(line)))

    scratch = tempfile.mkdtemp(prefix='hmap_readme_')
    work = os.path.join(scratch, 'repo')
    bin_dir = os.path.join(scratch, 'bin')
    os.makedirs(work)
    os.makedirs(os.path.join(scratch, 'shared'))
    os.makedirs(bin_dir)
    os.symlink(os.path.abspath(args.data), os.path.join(scratch, 'shared', 'data'))
    os.symlink(os.path.join(os.path.abspath(args.source), 'tests'), os.path.join(work, 'tests'))
    os.symlink(os.path.abspath(args.hmap), os.path.join(bin_dir, 'hmap'))
    env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get('PATH', ''))
    has_bags = subprocess.run([args.hmap, 'bag-info', '--help'], capture_output=True).returncode == 0

    used = set()
    failures = []
    ran = 0
    t_all = time.monotonic()
    for where, command in commands:
        if command.startswith('make'):
            print(f'-- {where}: not run (the build itself): {command}')
            continue
        if args.only and args.only not in command:
            continue
        normalised = ' '.join(command.split())
        if not has_bags and ('--bag' in normalised or 'bag-info' in normalised or 'make_test_bags' in normalised):
            print(f'-- {where}: not run (hmap built without ROS bag support): {command}')
            continue
        run = command
        for prefix, extra in SHORTENED.items():
            if normalised.startswith(prefix):
                used.add(prefix)
                run = f'{command} {extra}'
        t0 = time.monotonic()
        result = subprocess.run(['bash', '-c', 'set -euo pipefail; ' + run], cwd=work, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors='replace')
        ran += 1
        seconds = time.monotonic() - t0
        status = 'ok' if result.returncode == 0 else f'FAILED (exit {result.returncode})'
        print(f'-- {where}: {status} in {seconds:.1f} s: {run}', flush=True)
        if result.returncode != 0:
            tail = '\n'.join(result.stdout.rstrip().split('\n')[-15:])
            print(tail, flush=True)
            failures.append((where, run, tail))

    stale = [p for p in SHORTENED if p not in used and not args.only]
    if not has_bags:
        stale = [p for p in stale if '--bag' not in p]
    for prefix in stale:
        failures.append(('tests/apps/readme_commands_test.py', f'SHORTENED entry "{prefix}"', 'matches no command line'))
    print(f'{ran} command lines run in {time.monotonic() - t_all:.0f} s, {len(failures)} failed')
    for where, run, tail in failures:
        print(f'FAILED {where}: {run}: {tail.splitlines()[-1] if tail else ""}')
    if args.keep:
        print(f'scratch folder kept: {scratch}')
    else:
        shutil.rmtree(scratch, ignore_errors=True)
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
