#!/usr/bin/env python3
"""What knowing the pelvis would be worth: simulated patients deformed with their true device,
the models aligned on the renal arteries as a session's are, once as they are and once moved
with the true pelvis (`evarnode deform --pelvis-shift-mm`). Prints per patient the device-side
internal iliac ostium, the other one and the renal ostia against the truth (3D, mm), then the
means (docs/DEFORMATION.md, "The pelvis").

    scripts/pelvis_oracle.py --evarnode build/app/evarnode --physics beam --seeds 1-15 --work /tmp/oracle

Needs Python 3 with numpy and VTK (Debian: python3-numpy python3-vtk9).
"""
import argparse
import json
import os
import shutil
import subprocess

import numpy as np
import vtk


def landmarks(path):
    d = json.load(open(path))
    return {c['label']: np.array(c['position']) for c in d['markups'][0]['controlPoints']}


def translated_scene(src, dst, offset):
    """The scene in `src` moved by `offset` (mm): the registration to the renal arteries."""
    if os.path.exists(dst):
        shutil.rmtree(dst)
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns('truth', 'patient.json', 'device.mrk.json'))
    for f in os.listdir(dst):
        path = os.path.join(dst, f)
        if f.endswith('.stl'):
            r = vtk.vtkSTLReader()
            r.SetFileName(path)
            r.Update()
            polydata = r.GetOutput()
            points = polydata.GetPoints()
            for i in range(points.GetNumberOfPoints()):
                points.SetPoint(i, *(np.array(points.GetPoint(i)) + offset))
            w = vtk.vtkSTLWriter()
            w.SetFileName(path)
            w.SetInputData(polydata)
            w.SetFileTypeToBinary()
            w.Write()
        elif f.endswith('.mrk.json'):
            d = json.load(open(path))
            for m in d['markups']:
                for c in m['controlPoints']:
                    c['position'] = list(np.array(c['position']) + offset)
            json.dump(d, open(path, 'w'))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--evarnode', default='build/app/evarnode')
    ap.add_argument('--physics', default='beam', choices=['beam', 'conforming'])
    ap.add_argument('--seeds', default='1-15', help='first-last')
    ap.add_argument('--work', default='/tmp/pelvis-oracle')
    a = ap.parse_args()
    first, last = (int(x) for x in a.seeds.split('-'))
    os.makedirs(a.work, exist_ok=True)
    rows = []
    for n in range(first, last + 1):
        p = os.path.join(a.work, f'{a.physics}-{n}')
        if not os.path.exists(p):
            subprocess.run([a.evarnode, 'sim', 'patient', '--seed', str(n), '--difficulty', 'paper', '--physics', a.physics,
                            '--out', p], check=True, capture_output=True)
        patient = json.load(open(os.path.join(p, 'patient.json')))
        carrier = patient['ground_truth']['carrier'].split('_')[1]
        own, other = 'internal_iliac_' + carrier, 'internal_iliac_' + ('right' if carrier == 'left' else 'left')
        truth = landmarks(os.path.join(p, 'truth', 'landmarks.mrk.json'))
        pre = landmarks(os.path.join(p, 'landmarks.mrk.json'))
        renals = ('renal_left', 'renal_right')
        align = np.mean([truth[k] - pre[k] for k in renals], axis=0)
        aligned = p + '-aligned'
        translated_scene(p, aligned, align)
        pelvis = np.array(patient['posture_change']['pelvis_shift_mm']) - align
        row = []
        for extra in ([], ['--pelvis-shift-mm'] + [str(v) for v in pelvis]):
            out = p + ('-pelvis' if extra else '-plain')
            subprocess.run([a.evarnode, 'deform', '--scene', os.path.join(aligned, 'scene.json'), '--device',
                            os.path.join(p, 'device.mrk.json'), '--out', out, '--no-preview'] + extra,
                           check=True, capture_output=True)
            after = landmarks(os.path.join(out, 'landmarks.mrk.json'))
            row += [np.linalg.norm(after[own] - truth[own]), np.linalg.norm(after[other] - truth[other]),
                    np.mean([np.linalg.norm(after[k] - truth[k]) for k in renals])]
        rows.append(row)
        print(f'{a.physics}-{n}: device side {row[0]:5.1f} -> {row[3]:5.1f}, other {row[1]:5.1f} -> {row[4]:5.1f}, '
              f'renal {row[2]:4.1f} -> {row[5]:4.1f}', flush=True)
    r = np.array(rows)
    m = r.mean(axis=0)
    print(f'{a.physics}, {len(rows)} patients, mean (mm), without -> with the true pelvis: device side {m[0]:.2f} -> {m[3]:.2f}, '
          f'other {m[1]:.2f} -> {m[4]:.2f}, renal {m[2]:.2f} -> {m[5]:.2f}; device side worse by > 0.5 mm in '
          f'{int(np.sum(r[:, 3] > r[:, 0] + 0.5))}')


if __name__ == '__main__':
    main()
