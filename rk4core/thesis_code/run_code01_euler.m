% RUN_CODE01_EULER  Run the explicit Euler loop of Code 01's animation listing
% (code01_euler.m) on a protocol problem.
%
%   octave-cli --no-history --norc --quiet run_code01_euler.m PROBLEM.json TRAJECTORY.csv [printed|corrected]
%
% The problem must be linear with the stiffness matrix of two masses between
% two walls; its springs k1 (wall-m1), k2 (m1-m2), k3 (m2-wall) are read
% from the matrix and given to the program's inputs k1, k2, k3. Runs
% code01_euler.m from "%input mass_1" to the end of the loop as printed,
% without the video and drawing lines, with these lines replaced:
%   m1, m2, k1, k2, k3 = input(...)    -> the problem's masses and springs
%   x10=1; x20=1; v10=0; v20=0;        -> y0
%   simTime=1; tStep=0.01;             -> simTime = t_end - t0, tStep = h
% and one line added after "iterations=simTime/tStep;": iterations =
% round(iterations) (an integer up to round-off).
% "printed" keeps the accelerations as printed (the masses coupled through
% k3, k2 on the right wall: the stiffness matrix [k1+k3 -k3; -k3 k2+k3]).
% "corrected" couples them through k2 (a1 = (k2*(x2-x1) - k1*x1)/m1,
% a2 = (-(k2+k3)*x2 + k2*x1)/m2: [k1+k2 -k2; -k2 k2+k3], eqs. 2.6-2.7),
% in the two lines before the loop and the two in it.
% Writes t0 + (0:iterations)*tStep, x1, x2, v1, v2 and stats.json (nfev =
% iterations + 1 evaluations of the accelerations).
% Any error ends the run with one line "error: ..." on stderr and exit status 1.
try
  addpath(fileparts(mfilename('fullpath')));
  [drv_P, drv_variant] = thesis_problem(argv(), 'run_code01_euler', {'printed', 'corrected'});
  [drv_m, drv_k] = thesis_chain_springs(drv_P, 'run_code01_euler');
  if numel(drv_m) ~= 2
    error('run_code01_euler: Code 01 integrates two masses, the problem has %d', numel(drv_m));
  end
  drv_in = 'input(''Enter value of the spring constants (N/m): \n'');';
  drv_edits = {
    'm1 = input(''Enter value of mass_1 (kg): \n'');', '', 'm1 = drv_m(1);'
    'm2 = input(''Enter value of mass_2 (kg): \n'');', '', 'm2 = drv_m(2);'
    ['k1 = ' drv_in], '', 'k1 = drv_k(1);'
    ['k2 = ' drv_in], '', 'k2 = drv_k(2);'
    ['k3 = ' drv_in], '', 'k3 = drv_k(3);'
    'x10=1; % mass 1 initial position', '', 'x10 = drv_P.y0(1);'
    'x20=1; % mass 2 initial position', '', 'x20 = drv_P.y0(2);'
    'v10=0; % mass 1 initial velocity', '', 'v10 = drv_P.y0(3);'
    'v20=0; % mass 2 initial velocity', '', 'v20 = drv_P.y0(4);'
    'simTime=1; % simulation time', '', 'simTime = drv_P.t_end - drv_P.t0;'
    'tStep=0.01; % simulation time step', '', 'tStep = drv_P.h;'
    'iterations=simTime/tStep;', '', sprintf('iterations=simTime/tStep;\niterations=round(iterations);')
    '% Set up video', 'set(gcf, ''Position'', [50, 50, 700, 600])%positions of plot', ''
    '% Plot for the video', 'writeVideo(v,frame)', ''
  };
  if strcmp(drv_variant, 'corrected')
    drv_edits(end+1:end+4, :) = {
      'a1(1,:)=( k3*(x20-x10) + -k1*x10)/m1;', '', 'a1(1,:)=( k2*(x20-x10) + -k1*x10)/m1;'
      'a2(1,:)=(-(k2+k3)*x20''+k3*x10)/m2;', '', 'a2(1,:)=(-(k2+k3)*x20''+k2*x10)/m2;'
      'a1(n,:) = (k3*((x2(n,:)) - (x1(n,:))) + -k1*(x1(n,:)))/m1;', '', 'a1(n,:) = (k2*((x2(n,:)) - (x1(n,:))) + -k1*(x1(n,:)))/m1;'
      'a2(n,:) = (-(k2+k3)*(x2(n,:)) + k3*(x1(n,:)))/m2;', '', 'a2(n,:) = (-(k2+k3)*(x2(n,:)) + k2*(x1(n,:)))/m2;'
    };
  end
  eval(thesis_listing(fullfile(fileparts(mfilename('fullpath')), 'code01_euler.m'), ...
                      '%input mass_1', 'close(v);', drv_edits));
  thesis_write(drv_P.trajectory, drv_P.t0 + (0:iterations)*tStep, [x1 x2 v1 v2], iterations + 1);
catch drv_err
  fprintf(stderr, 'error: %s\n', drv_err.message);
  exit(1);
end
