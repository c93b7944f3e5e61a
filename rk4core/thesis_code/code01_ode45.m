% Thesis Code 01, first two listings: the two-mass chain of Table 4.1 with
% ode45 (thesis.txt lines 968-1035), transcribed as printed.
%
% Needs testcode.m (the right-hand side y' = CC*y), which the thesis does
% not print; see that file. run_code01_ode45.m runs lines "%Degree of
% freedom" .. "[tsol,ysol] = ode45(...)" of this file with the problem's
% inputs (protocol of rk4core/command.py).
%
% OCR repairs (thesis.txt line: printed -> repaired; why it is OCR, not the author's):
%   1013-1014: "% plot(y1(idxmin),...,...", next line "'MarkerSize',10)"
%       -> the second line starts with "%" too. The statement was
%       commented out across its "..." continuation; a bare
%       "'MarkerSize',10)" line does not parse, so no figure (4.1, 4.2)
%       could have been drawn by the printed text; the layout dropped the
%       leading "%" of the wrapped line.
%   1016-1017: same (a "%" in front of "           'MarkerSize',10)").
%   1028: "hold on xlabel('Time(s)'); ylabel('Velocity (m/s)');" -> "hold on"
%       and "xlabel('Time(s)'); ylabel('Velocity (m/s)');" on two lines: two
%       lines merged by the layout ("hold on xlabel(...)" is a command-syntax
%       call hold('on', ...) and fails).
%   1034: "hold on xlabel(...); ylabel(...); title('Velocity VS Time')
%       legend('Mass 1','Mass 2');" -> split after "hold on" and after
%       "title('Velocity VS Time')" (a statement followed by another with no
%       separator does not parse).
% Not repaired (the author's, kept as printed): "global CC" after CC is
% assigned (Octave warns and keeps the local value), the axis labels of
% the third figure, the names idxmin/idxmax (swapped).
% Indentation is normalised.
clc;
clear all;
%Degree of freedom
%input mass_1
M1 = 0.815
%input mass_2
M2 = 3.099
%Inputs for spring constants.
K1 = 41.5
%Inputs for spring constants.
K2 = 138
%Inputs for spring constants.
K3 = 157.8
%Mass matrix
M = [M1 0; 0 M2];
%Stiffness matrix
K = [K1+K2 -K2; -K2 K2+K3];
%Estimation natural frequncies and mode shapes
[modeShape fr] = eig(K,M);
%Coffecient matrix
A00 = zeros(2);
A11 = eye(2);
CC = [A00 A11; -inv(M)*K A00]; global CC
%%Time step and time vector
max_freq = max(sqrt(diag(fr))/(2*pi)); %maximum frequency in Hz
dt = 1/(max_freq*20);
Nstep = 100;
time = 0:dt:Nstep*dt;
y0 = [0.005 0.005 0 0]; %[disp1 disp2 vol1 vol2] inatial condition
[tsol,ysol] = ode45('testcode',time,y0);
y1 = ysol(:,1);
y2 = ysol(:,2);
v1 = ysol(:,3);
v2 = ysol(:,4);
idxmin = find(y1 == max(y1))
idxmax = find(y1 == min(y1))
figure()
plot(time,y1,'--r','linewidth',1.5);
hold on
plot(time,y2,'-.b','linewidth',1.5);
hold off
% plot(y1(idxmin),y1(idxmax),'*','MarkerFaceColor','red',...
%     'MarkerSize',10)
% % hold on
% % plot(y2(idxmax),y1(idxmax),'-p','MarkerFaceColor','black',...
%            'MarkerSize',10)
% hold off
xlabel('Time (s)');
ylabel('Displacement (m)');
title('Displacement VS Time')
legend('Mass 1', 'Mass 2');
grid on
figure()
plot(time,v1,'--r','linewidth',1.5);
hold on
plot(time, v2, '-.b', 'linewidth', 1.5);
hold on
xlabel('Time(s)'); ylabel('Velocity (m/s)');
title('Velocity VS Time')
legend('Mass 1','Mass 2');
grid on
figure()
plot(y1,y2,'--r','linewidth',1);
hold on
xlabel('Time(s)'); ylabel('Velocity (m/s)'); title('Velocity VS Time')
legend('Mass 1','Mass 2');
grid on
