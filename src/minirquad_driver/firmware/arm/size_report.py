"""Flash and RAM of the cross-compiled firmware core against the board, and a check that no
heap or C++ runtime support was linked in. Called by `make size`; exit 1 on any failure.

Flash = text + data (the initial values of .data live in flash); static RAM = data + bss;
the stack comes on top of that, so the worst single function frames are listed as well
(from -fstack-usage; a call chain's depth is their sum along the chain).
"""
import argparse
import re
import subprocess
import sys
from pathlib import Path

FORBIDDEN = re.compile(r'^(malloc|free|calloc|realloc|_malloc_r|_free_r|_sbrk|_Zn[wa]j\w*|'
                       r'_Zd[la]Pv\w*|__cxa_\w+|__gxx_personality\w*|_Unwind_\w+)$')


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('elf')
    p.add_argument('--size', required=True)
    p.add_argument('--nm', required=True)
    p.add_argument('--flash', type=int, required=True)
    p.add_argument('--ram', type=int, required=True)
    p.add_argument('--stack-usage', type=Path, help='folder with the .su files')
    a = p.parse_args()
    out = subprocess.run([a.size, '-A', a.elf], check=True, capture_output=True,
                         text=True).stdout
    sec = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith('.') and parts[1].isdigit():
            sec[parts[0]] = int(parts[1])
    text = sec.get('.text', 0) + sec.get('.ARM.exidx', 0)
    data, bss = sec.get('.data', 0), sec.get('.bss', 0)
    flash, ram = text + data, data + bss
    print(f'firmware core for the SAMD21 (Cortex-M0+, -Os), {Path(a.elf).name}:')
    print(f'  flash {flash:7d} B of {a.flash} ({100 * flash / a.flash:.1f} %): '
          f'text {text} + data {data}')
    print(f'  RAM   {ram:7d} B of {a.ram} ({100 * ram / a.ram:.1f} %): '
          f'data {data} + bss {bss}, stack not included')
    symbols = subprocess.run([a.nm, '-C', '--format=posix', a.elf], check=True,
                             capture_output=True, text=True).stdout
    raw = subprocess.run([a.nm, '--format=posix', a.elf], check=True, capture_output=True,
                         text=True).stdout
    bad = sorted({ln.split()[0] for ln in raw.splitlines() if FORBIDDEN.match(ln.split()[0])})
    floats = sorted({ln.split()[0] for ln in symbols.splitlines()
                     if ln.startswith('__aeabi_f') or ln.startswith('__aeabi_i2f')})
    print(f'  soft-float helpers linked: {len(floats)} (no FPU on the M0+)')
    if a.stack_usage and a.stack_usage.is_dir():
        frames = []
        for su in a.stack_usage.glob('*.su'):
            for ln in su.read_text().splitlines():
                parts = ln.split('\t')
                if len(parts) >= 2 and parts[1].isdigit():
                    frames.append((int(parts[1]), parts[0].split(':')[-1]))
        frames.sort(reverse=True)
        print('  largest stack frames: ' + ', '.join(f'{f} {n} B' for n, f in frames[:4]))
    ok = True
    if bad:
        print('  FAIL: heap or C++ runtime support linked in: ' + ', '.join(bad))
        ok = False
    else:
        print('  no malloc/free/new/delete/__cxa_*/unwinder symbols')
    if flash > a.flash or ram > a.ram:
        print('  FAIL: over the board budget')
        ok = False
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
