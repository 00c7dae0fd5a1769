"""`rosdep install --from-paths src -iy` can resolve every dependency: each key of every
package.xml is a package of this workspace or a key of requirements/rosdep_keys.yaml, the
checked list of keys with the rosdistro file that defines each (checked against the rosdep
database; no network here, so the list is the record). No ROS needed."""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
TAGS = ('depend', 'build_depend', 'build_export_depend', 'buildtool_depend', 'exec_depend',
        'test_depend', 'doc_depend')
SOURCE = re.compile(r'^(rosdep/(base|python)\.yaml|jazzy/distribution\.yaml \([a-z0-9_]+\))$')


def checked() -> dict[str, str]:
    return yaml.safe_load((REPO / 'requirements' / 'rosdep_keys.yaml').read_text())


def package_keys() -> dict[str, set[str]]:
    """key -> the workspace packages that use it."""
    out: dict[str, set[str]] = {}
    for xml in sorted((REPO / 'src').glob('*/package.xml')):
        root = ET.parse(xml).getroot()
        for tag in TAGS:
            for e in root.iter(tag):
                out.setdefault(e.text.strip(), set()).add(root.findtext('name'))
    return out


def workspace() -> set[str]:
    return {ET.parse(x).getroot().findtext('name') for x in (REPO / 'src').glob('*/package.xml')}


def test_every_key_is_checked_or_a_workspace_package():
    keys, ws, known = package_keys(), workspace(), checked()
    unknown = {k: sorted(p) for k, p in keys.items() if k not in ws and k not in known}
    assert not unknown, f'rosdep keys not in requirements/rosdep_keys.yaml: {unknown}'


def test_the_list_is_well_formed_and_used():
    known, used = checked(), set(package_keys())
    bad = {k: v for k, v in known.items() if not SOURCE.match(str(v))}
    assert not bad, f'entries without a rosdistro source: {bad}'
    assert not sorted(set(known) - used), 'keys no package.xml uses: drop them'
    # A python key names its rosdep file; a ROS package is released in Jazzy.
    for k, v in known.items():
        assert v.startswith('rosdep/') == k.startswith('python3-'), (k, v)


def test_invented_keys_stay_out():
    # Neither is in rosdistro's rosdep files: dask has no key at all (optional, pip), and
    # rosbags' key is python3-rosbags-pip.
    assert {'python3-dask', 'python3-rosbags'}.isdisjoint(set(package_keys()) | set(checked()))


def test_optional_dask_is_a_pip_extra_not_a_rosdep_key():
    setup = (REPO / 'src' / 'rftgls_core' / 'setup.py').read_text()
    assert "'distributed': ['dask[distributed]']" in setup
