% Thesis Code 02, first two listings: n equal masses between two walls,
% semi-implicit Euler (thesis.txt lines 1170-1237), transcribed as printed.
% (Code 02's third listing, the lattice dispersion plots of lines 1240-1356,
% integrates nothing and is not transcribed; references/dispersion.py
% computes those curves.)
%
% run_code02.m runs lines "% Assume spring constants .." .. the loop's last "end" of this
% file with the problem's inputs (protocol of rk4core/command.py).
%
% OCR repairs (thesis.txt line: printed -> repaired; why it is OCR, not the author's):
%   1176-1177: "m = input('Enter value of Mass Weight (kg):" + "<blanks>\n');"
%       -> one line "m = input('Enter value of Mass Weight (kg): \n');" (the
%       layout broke the string; a string cannot span lines).
%   1185: "mode=2; % must be <= n</pre>" -> "mode=2; % must be <= n" ("</pre>"
%       is HTML markup of the conversion, inside a comment).
%   1192: "% make the K matrix into a full matrix K=full(K);" -> the comment
%       line and "K=full(K);" on the next line: the comment announces the
%       statement, and the same comment-and-statement merge of the layout is
%       on lines 1050, 1090 and 1113 (Code 01) and 1251 (this appendix).
%       (In Octave the sparse K gives the same numbers to round-off.)
% Not repaired (the author's, kept as printed): tVector = tStep.*(1:iterations)
% labels the state after i-1 steps (row i) as time i*tStep, one step late,
% and the run covers t - tStep, not t; a(1,:) stays 0.
% Indentation is normalised.
clear all;
close all;
clc;
% Assume spring constants are equivalent and masses are equivelent.
%input Mass Value
m = input('Enter value of Mass Weight (kg): \n');
%Input for spring constants.
k = input('Enter value of the spring constants (N/m): \n');
%Input for spring constants.
n = input('Number of Masses: \n');
% simulation time
t = input('Simulation time period: \n');
tStep=0.001;
mode=2; % must be <= n
% Create mass and stiffness matrices based on generalized FBD's
% mass matrix is an identity matrix
M=m.*eye(n);
e=ones(n,1);
% stiffness matrix
K=spdiags([-k.*e 2*k.*e -k.*e],-1:1,n,n);
% make the K matrix into a full matrix
K=full(K);
% Returns phi (eigenvectors) and lambda (eigenvalues) - M*phi*lambda=K*phi
[phi,lambda]=eig(K,M);
% Get natural frequencies from eigenvalues
Wn=sqrt(diag(lambda));
% Time step setup
% total number of iterations
iterations=t/tStep;
% time vector (for plotting purposes)
tVector=tStep.*(1:iterations);
% Pre-allocate arrays for speed
x=zeros(iterations,n);
v=zeros(iterations,n);
a=zeros(iterations,n);
% initial displacements governed by desired mode
x(1,:)=phi(:,mode);
% Iteratively solve equations of motion using Semi-implicit Euler
for i=2:iterations
    for j=1:n
        a(i,j)=(-K(j,:)./M(j,j))*(x(i-1,:)');
        v(i,j)=v(i-1,j)+a(i,j)*tStep;
        x(i,j)=x(i-1,j)+v(i,j)*tStep;
    end
end
% Plot the results
for k=1:n
    subplot(3,1,1); hold on; grid on;
    plot(tVector,x(:,k))
    subplot(3,1,2); hold on; grid on;
    plot(tVector,v(:,k))
    subplot(3,1,3); hold on; grid on;
    plot(tVector,a(:,k))
end
subplot(3,1,1);
title('Position, Velocity, and Acceleration as a Function of Time');
ylabel('Position (m)');
grid on;
subplot(3,1,2);
ylabel('Velocity (m/s)');
subplot(3,1,3);
ylabel('Acceleration (m/s^2)');
xlabel('Time (s)');
grid on;
